"""Parameters at run time on a running graph: phase, unwrap and cloud as OS processes, ``dptpu param`` as another.

``dptpu param set /cloud frame_id camera_optical_frame`` changes the frame of the next cloud and depth image;
``param set /unwrap method bogus`` is refused with its reason and ``method`` stays ``mf`` (the next scan is still
unwrapped by MF); a read-only parameter (``/cloud rig``) is refused and keeps its value, and ``param describe`` says it
is read-only; ``min_confidence`` set to
1.0 leaves the next cloud with fewer points than the scan before.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np

from dptpu.fpp.calibration import save_rig
from dptpu.graph import Parameter
from dptpu.graph.parameter_client import AsyncParameterClient
from dptpu.messages import AbsolutePhase, FringeFrame, PointCloud2
from dptpu.nodes.harness import fringe_frames
from tests.nodes.test_cloud_scene import plane_scene

FREQUENCIES = (16.0, 1.0)


def _dptpu(*args: str) -> tuple[int, str]:
    """The real ``dptpu`` command in this test's domain (the environment carries it): (exit code, stdout+stderr)."""
    result = subprocess.run([sys.executable, "-m", "dptpu.cli.main", *args], capture_output=True, text=True,
                            timeout=120, env=dict(os.environ))
    return result.returncode, result.stdout + result.stderr


def _set(client: AsyncParameterClient, name: str, value):
    future = client.set_parameters([Parameter(name, value=value)])
    assert future.wait(timeout_sec=20), f"no answer to set_parameters {name}"
    return future.result().results[0]


def _reason(result) -> str:
    assert not result.successful
    return result.reason


def _get(client: AsyncParameterClient, name: str):
    future = client.get_parameters([name])
    assert future.wait(timeout_sec=20), f"no answer to get_parameters {name}"
    return client.values_of(future.result())[0]


def test_param_set_changes_the_next_cloud_and_a_bad_value_is_refused(spawn_node, probe, tmp_path):
    scene = plane_scene()
    rig_path = save_rig(scene.rig, tmp_path / "rig.yaml")
    nodes = [spawn_node("dptpu.nodes.phase", "--ros-args", "-p", "timeout_s:=1.0"),
             spawn_node("dptpu.nodes.unwrap", "--ros-args", "-p", "method:=mf"),
             spawn_node("dptpu.nodes.cloud", "--ros-args", "-p", f"rig:={rig_path}", "-p", "min_confidence:=0.0")]
    camera = probe.publisher(FringeFrame, "/camera/image_raw")
    points = probe.subscribe(PointCloud2, "/scanner/points")
    absolute = probe.subscribe(AbsolutePhase, "/scanner/absolute_phase")
    stacks = [scene.frames(f, seed=i) for i, f in enumerate(FREQUENCIES)]
    sequence_id = 0

    def scan() -> tuple[PointCloud2, AbsolutePhase]:
        nonlocal sequence_id
        sequence_id += 1
        frames = fringe_frames(stacks, FREQUENCIES, sequence_id=sequence_id,
                               stamp_ns=1_800_000_000_000_000_000 + sequence_id * 1_000_000_000)
        for frame in frames:
            camera.publish(frame)
        stamp = frames[-1].image.header.stamp  # a scan is stamped with its last frame
        return (points.wait_for(lambda c: c.header.stamp == stamp, timeout=30.0),
                absolute.wait_for(lambda a: a.header.stamp == stamp, timeout=30.0))

    deadline = time.monotonic() + 60.0  # until the processes are up and connected a scan may fall between them
    while not points.messages:
        assert time.monotonic() < deadline, "no cloud within 60 s: " + "; ".join(p.stderr[-300:] for p in nodes)
        if camera.get_subscription_count():
            sequence_id += 1
            for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=sequence_id):
                camera.publish(frame)
        time.sleep(1.0)
    before, _ = scan()
    assert before.header.frame_id == "scanner_optical_frame"
    points_before = int(np.count_nonzero(np.isfinite(before.to_array(["z"]))))

    # the two commands, through the real CLI; the rest through the same services from the probe
    assert _dptpu("param", "set", "/cloud", "frame_id", "camera_optical_frame") == (0, "Set parameter successful\n")
    code, out = _dptpu("param", "set", "/unwrap", "method", "bogus")
    assert (code, out) == (1, "Setting parameter failed: parameter method must be one of mf, mw, nt, heterodyne; "
                              "got 'bogus'\n")
    # which is which, as ros2 param describe says it (the docstrings of ParameterRules name this command)
    assert _dptpu("param", "describe", "/cloud", "rig", "frame_id") == (0, (
        "Parameter name: rig\n  Type: string\n  Description: a dptpu-rig/1 file; restart the node to change it\n"
        "  Constraints:\n    Read only: true\n"
        "Parameter name: frame_id\n  Type: string\n"
        "  Description: header.frame_id of the next clouds and images (and TF's)\n"))
    cloud, unwrap = AsyncParameterClient(probe.node, "/cloud"), AsyncParameterClient(probe.node, "/unwrap")
    assert cloud.wait_for_services(timeout_sec=20) and unwrap.wait_for_services(timeout_sec=20)
    assert _get(unwrap, "method") == "mf"
    assert _reason(_set(cloud, "rig", "other.yaml")) == "Trying to set a read-only parameter: rig"
    assert _reason(_set(cloud, "min_confidence", 1.5)) == "min_confidence must be within [0, 1]; got 1.5"

    after, after_phase = scan()
    assert after.header.frame_id == "camera_optical_frame"
    assert after_phase.method == "mf"
    np.testing.assert_array_equal(np.isfinite(after.to_array(["z"])), np.isfinite(before.to_array(["z"])))

    # a threshold: no classical rounding margin reaches 1.0 on a noisy capture, so fewer points (none at most)
    assert _set(cloud, "min_confidence", 1.0).successful
    strict, _ = scan()
    assert int(np.count_nonzero(np.isfinite(strict.to_array(["z"])))) < points_before
    assert all(p.proc.poll() is None for p in nodes)
