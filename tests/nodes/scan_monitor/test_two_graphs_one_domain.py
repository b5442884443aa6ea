"""Two graphs in one domain mix (issue 18, outside tester): a second scan monitor reported the other graph's scans
as its own, silently. The monitor now sees a second live node of the name of one of its status nodes, says what
to do (docs/launch.md: a domain of its own for each graph) and calls every scan UNTRUSTED while both run."""
from __future__ import annotations

import os

import numpy as np

from dptpu.fpp.calibration import save_rig
from dptpu.messages import AbsolutePhase, Header, Time
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.scan_monitor import ScanMonitorNode
from tests.nodes.conftest import TEST_DOMAIN_ID
from tests.nodes.test_cloud_scene import plane_scene


def _scan(scene, sequence_id: int) -> AbsolutePhase:
    psi = scene.absolute_phase(16.0).astype(np.float32)
    return AbsolutePhase(
        header=Header(stamp=Time.from_ns(1_700_000_000_000_000_000 + sequence_id * 10**9), frame_id="camera"),
        sequence_id=sequence_id, frequency=16.0, fringe_axis="x", projector_width=912, projector_height=1140,
        absolute_phase=psi, fringe_order=np.floor(psi / (2 * np.pi)).astype(np.int32), valid=np.ones(psi.shape, bool),
        reliability=np.full(psi.shape, 0.9, np.float32), method="mf")


def test_a_second_graphs_node_of_the_same_name_makes_the_scans_untrusted_until_it_leaves(node_env, spawn_node,
                                                                                       tmp_path):
    scene = plane_scene()
    rig_path = save_rig(scene.rig, tmp_path / "rig.yaml")
    with NodeHarness(domain_id=TEST_DOMAIN_ID, private=False) as harness:  # node_env's private domain
        harness.start(CloudNode, rig=str(rig_path))
        monitor = harness.start(ScanMonitorNode, ground_truth=False, trigger_latency=False, scan_timeout_s=60.0)
        source = harness.publisher(AbsolutePhase, "/scanner/absolute_phase")
        harness.connect()
        source.publish(_scan(scene, 1))
        assert harness.spin_until(lambda: monitor.reported >= 1, timeout_s=30.0)
        assert (monitor.records[0]["outcome"], monitor.other_graph) == ("ok", "")
        # a second graph's cloud node, started in the same domain (its own process)
        other = spawn_node("dptpu.nodes.cloud", "--ros-args", "-p", f"rig:={rig_path}")
        assert harness.spin_until(lambda: bool(monitor.other_graph), timeout_s=60.0), other.stderr
        pids = ", ".join(str(pid) for pid in sorted([other.proc.pid, os.getpid()]))
        assert monitor.other_graph == f"2 nodes named /cloud (pids {pids})"
        source.publish(_scan(scene, 2))
        assert harness.spin_until(lambda: monitor.reported >= 2, timeout_s=30.0)
        assert monitor.records[1]["outcome"] == "untrusted"
        assert monitor.records[1]["reason"] == f"two graphs in one domain: {monitor.other_graph}"
        other.terminate()
        other.proc.wait(timeout=30)
        assert harness.spin_until(lambda: not monitor.other_graph, timeout_s=60.0)
        source.publish(_scan(scene, 3))
        assert harness.spin_until(lambda: monitor.reported >= 3, timeout_s=30.0)
        assert monitor.records[2]["outcome"] == "ok"
