"""Projector and camera started by ``dptpu launch`` from a launch file: Triggers flow into paired frames.

The projector runs on ``loop://`` (its trigger-box emulator) and the camera on ``viky.cti``
(free-running, 200 frames/s against 20 ms patterns), so each displayed pattern gets the next frame.
"""

from __future__ import annotations

import textwrap
import time

import numpy as np

from dptpu.graph.interfaces import Trigger as TriggerService
from dptpu.messages import FringeFrame, ScanStatus
from tests.tools.launch.conftest import LaunchProcess

LAUNCH = """
launch:
  - node:
      pkg: dptpu
      exec: projector
      name: projector
      param:
        - {name: port, value: "loop://"}
        - {name: sequence, value: "4x3,1x3"}
        - {name: exposure_us, value: 20000}
  - node:
      pkg: dptpu
      exec: camera
      name: camera
      param:
        - {name: trigger_mode, value: free-running}
        - {name: frame_rate_hz, value: 200.0}
        - {name: width, value: 160}
        - {name: height, value: 120}
"""


def test_launch_file_runs_projector_and_camera_and_frames_carry_their_triggers(probe, tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text(textwrap.dedent(LAUNCH))
    frames = probe.subscribe(FringeFrame, "/camera/image_raw")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    launch = LaunchProcess(path)
    try:
        launch.wait_for(r"6 patterns loaded \(loop://: EMULATED box", timeout_s=20)
        launch.wait_for(r"camera Machine Vision Games Ltd\. Viky serial 0: 160x120 Mono8", timeout_s=20)
        client = probe.client(TriggerService, "/projector/start_scan")
        assert client.wait_for_service(timeout_sec=10)
        frames.wait_for_publishers(1)  # the camera's frames reach the probe before the first scan
        # the camera's Trigger subscription is announced; the runtime connects a late subscriber within 1 s
        # (docs/graph.md), and a Trigger published before that is lost, so give the link that second
        deadline = time.monotonic() + 10
        while probe.node.count_subscribers("/projector/trigger") < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(1.0)
        for sequence_id in (1, 2):
            assert client.call(TriggerService.Request(), timeout_sec=5).message == f"scan {sequence_id} queued"
            status.wait_for(lambda s, i=sequence_id: s.sequence_id == i and s.state == "done", timeout=10)
        received = frames.wait(12, timeout=10)
        assert [(f.trigger.sequence_id, f.trigger.pattern_index, f.trigger.frequency, f.trigger.step)
                for f in received] == [(s, i, 4.0 if i < 3 else 1.0, i % 3) for s in (1, 2) for i in range(6)]
        assert all(np.count_nonzero(f.image.to_array() == 0) == 400 for f in received)
        assert not [s for s in status.messages if s.state == "failed"]
        launch.process.terminate()
        assert launch.finish(timeout_s=15) == 0
    finally:
        launch.kill_everything()
