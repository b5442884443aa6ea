"""phase, unwrap and cloud as three OS processes (``python -m dptpu.nodes.X``), fed over real ZeroMQ by the test.

The test process is the camera (a probe node publishing FringeFrames of the analytic plane) and the robot
(collecting PointCloud2 and ScanStatus). Malformed messages injected on three topics are reported by the node
concerned, and every node stays up for the next scan.
"""
from __future__ import annotations

import time

import numpy as np

from dptpu.fpp.calibration import save_rig
from dptpu.messages import AbsolutePhase, FringeFrame, Image, PhaseMaps, PointCloud2, ScanStatus
from dptpu.nodes.harness import fringe_frames
from tests.nodes.test_cloud_pipeline import DEPTH_MAX_BOUND_M, DEPTH_RMS_BOUND_M
from tests.nodes.test_cloud_scene import plane_scene

FREQUENCIES = (16.0, 1.0)


def test_three_node_processes_turn_frames_into_clouds_and_survive_malformed_input(spawn_node, probe, tmp_path):
    scene = plane_scene()
    rig_path = save_rig(scene.rig, tmp_path / "rig.yaml")
    nodes = {
        "phase": spawn_node("dptpu.nodes.phase", "--ros-args", "-p", "timeout_s:=1.0"),
        "unwrap": spawn_node("dptpu.nodes.unwrap", "--ros-args", "-p", "method:=mf"),
        "cloud": spawn_node("dptpu.nodes.cloud", "--ros-args", "-p", f"rig:={rig_path}"),
    }
    camera = probe.publisher(FringeFrame, "/camera/image_raw")
    points = probe.subscribe(PointCloud2, "/scanner/points")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    stacks = [scene.frames(f, seed=i) for i, f in enumerate(FREQUENCIES)]

    # warm-up: until the three processes are up and connected, a scan may fall between them; repeat scan 1..n
    deadline, sequence_id = time.monotonic() + 60.0, 0
    while not points.messages:
        assert time.monotonic() < deadline, "no cloud within 60 s: " + "; ".join(
            f"{name} exit {p.proc.poll()} stderr {p.stderr[-300:]}" for name, p in nodes.items())
        if camera.get_subscription_count():
            sequence_id += 1
            for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=sequence_id):
                camera.publish(frame)
        time.sleep(1.0)

    # malformed input on three topics
    injector_maps = probe.publisher(PhaseMaps, "/scanner/phase")
    injector_phase = probe.publisher(AbsolutePhase, "/scanner/absolute_phase")
    assert injector_maps.wait_for_subscriptions(1, timeout_sec=10.0)  # unwrap (the cloud takes /scanner/intensity)
    assert injector_phase.wait_for_subscriptions(1, timeout_sec=10.0)
    bad_frames = fringe_frames(stacks, FREQUENCIES, sequence_id=100)
    bad_frames[2].image = Image.from_array(np.zeros((60, 80), np.uint8), header=bad_frames[2].image.header)
    for frame in bad_frames:
        camera.publish(frame)
    injector_maps.publish(PhaseMaps(sequence_id=101, frequencies=np.array([16.0, 1.0]),
                                    phases=np.full((2, 120, 160), 9.0, np.float32),
                                    modulation=np.ones((2, 120, 160), np.float32), valid=np.ones((120, 160), bool)))
    injector_phase.publish(AbsolutePhase(sequence_id=102, frequency=16.0, absolute_phase=np.zeros((4, 4), np.float32),
                                         fringe_order=np.zeros((4, 4), np.int32), valid=np.ones((4, 4), bool),
                                         reliability=np.ones((4, 4), np.float32)))
    failed = {s.node: s for s in [status.wait_for(lambda s, i=i: s.sequence_id == i and s.state == "failed")
                                  for i in (100, 101, 102)]}
    assert "pattern 2 (f=16, step 2 of 4) is 80x60 uint8; the scan's first frame was 160x120 uint8" \
        in failed["/phase"].reason
    assert "psi_h must be a wrapped phase in [0, 2*pi)" in failed["/unwrap"].reason
    assert failed["/cloud"].reason == "cannot triangulate scan 102: absolute_phase is 4x4 pixels; the rig's camera " \
                                      "is 160x120"
    assert nodes["phase"].wait_for_stderr("scan 100 dropped")

    # every process is still up, and the next scan is fine
    final, stamp_ns = sequence_id + 200, 1_800_000_000_000_000_000
    frames = fringe_frames(stacks, FREQUENCIES, sequence_id=final, stamp_ns=stamp_ns)
    for frame in frames:
        camera.publish(frame)
    last_stamp = frames[-1].image.header.stamp  # a cloud is stamped with its scan's last frame
    cloud = points.wait_for(lambda c: c.header.stamp == last_stamp, timeout=30.0)
    assert all(p.proc.poll() is None for p in nodes.values())
    xyz = cloud.to_array(["x", "y", "z"])
    depth_error = xyz[..., 2] - scene.points_mm[..., 2] * 1e-3
    assert np.sqrt(np.mean(depth_error**2)) < DEPTH_RMS_BOUND_M and np.abs(depth_error).max() < DEPTH_MAX_BOUND_M
    done = status.wait_for(lambda s: s.sequence_id == final and s.node == "/cloud")
    assert (done.level, done.state, done.valid_pixels, done.total_pixels) == (ScanStatus.OK, "done", 19200, 19200)


def test_a_node_with_bad_parameters_exits_2_with_the_reason(spawn_node):
    cloud = spawn_node("dptpu.nodes.cloud")
    assert cloud.wait(timeout=30.0) == 2
    assert "cloud: error: parameter rig must name a dptpu-rig/1 calibration file" in cloud.stderr


def test_the_three_nodes_validate_in_a_launch_file(tmp_path):
    from dptpu.tools.launch import load_launch_file

    launch = tmp_path / "scanner.yaml"
    launch.write_text(
        "launch:\n"
        "  - group:\n"
        "      - push_ros_namespace: {namespace: /scanner}\n"
        "      - node: {pkg: dptpu, exec: phase, name: phase, param: [{name: timeout_s, value: 1.0}]}\n"
        "      - node: {pkg: dptpu, exec: unwrap, name: unwrap, param: [{name: method, value: nt}]}\n"
        "      - node: {pkg: dptpu, exec: cloud, name: cloud, param: [{name: rig, value: rig.yaml}]}\n")
    plan = load_launch_file(str(launch), {})
    commands = {node.label: node.command for node in plan.nodes}
    assert set(commands) == {"phase", "unwrap", "cloud"}
    assert commands["unwrap"][1:3] == ["-m", "dptpu.nodes.unwrap"] and "method:=nt" in commands["unwrap"]
