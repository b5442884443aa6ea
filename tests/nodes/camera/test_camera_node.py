"""The camera node as a real process on real GenTL producers, over real ZeroMQ to a probe node.

The probe plays the projector: it publishes Triggers on /projector/trigger and collects FringeFrames,
CameraInfo and ScanStatus. ``viky.cti`` (genicam wheel) is free-running only; ``TLSimu.cti``
(genicam2 wheel) has a software trigger.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from dptpu.fpp.calibration import DeviceModel, Rig, save_rig
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import CameraInfo, FringeFrame, ScanStatus, Trigger
from dptpu.nodes.camera.genicam_producers import shipped_producer
from tests.graph.nodes.shm_peer import is_shared

NODE = "dptpu.nodes.camera"
VIKY = shipped_producer("viky.cti")
TLSIMU = shipped_producer("TLSimu.cti")
FAST = ["-p", "reconnect_initial_s:=0.1", "-p", "reconnect_max_s:=0.4"]
SMALL = ["-p", "width:=160", "-p", "height:=120"]


def triggers(sequence_id, count):
    return [Trigger(sequence_id=sequence_id, pattern_index=i, pattern_count=count, frequency=8.0, steps=count, step=i)
            for i in range(count)]


def publish_spaced(publisher, messages, gap_s=0.03):
    import time

    for message in messages:
        publisher.publish(message)
        time.sleep(gap_s)


def write_rig(path):
    K = np.array([[200.0, 0.0, 79.5], [0.0, 201.0, 59.5], [0.0, 0.0, 1.0]])
    camera = DeviceModel(K=K, dist=[-0.1, 0.02, 0.001, -0.002, 0.0], R=np.eye(3), T=[0.0, 0.0, 0.0], size=(160, 120))
    projector = DeviceModel(K=np.array([[1500.0, 0.0, 456.0], [0.0, 1500.0, 570.0], [0.0, 0.0, 1.0]]), dist=[0] * 5,
                            R=np.eye(3), T=[-100.0, 0.0, 0.0], size=(912, 1140))
    return save_rig(Rig(camera=camera, projector=projector), path), K


def test_viky_free_running_pairs_each_trigger_with_a_real_frame_and_publishes_camera_info(spawn_node, probe,
                                                                                           tmp_path):
    rig_path, K = write_rig(tmp_path / "rig.yaml")
    frames = probe.subscribe(FringeFrame, "/camera/image_raw")
    trigger_pub = probe.publisher(Trigger, "/projector/trigger")
    node = spawn_node(NODE, "--ros-args", "-p", "trigger_mode:=free-running", "-p", "frame_rate_hz:=100.0",
                      "-p", "serial:=1", "-p", f"rig:={rig_path}", *SMALL, *FAST)
    assert node.wait_for_stderr("camera Machine Vision Games Ltd. Viky serial 1: 160x120 Mono8, trigger mode "
                                "free-running", timeout=20)
    assert trigger_pub.wait_for_subscriptions(1, timeout_sec=10)
    frames.wait_for_publishers(1)  # the camera's frames reach the probe before the first Trigger
    sent = triggers(3, 6)
    publish_spaced(trigger_pub, sent)
    received = frames.wait(6, timeout=10)
    assert [f.trigger for f in received] == sent  # one frame per Trigger, in order, with that Trigger
    for frame in received:
        image = frame.image.to_array()
        assert image.shape == (120, 160) and frame.image.encoding == "mono8"
        assert np.count_nonzero(image == 0) == 400  # viky's 20x20 square
        assert frame.image.header.frame_id == "scanner_optical_frame"
    stamps = [f.image.header.stamp.sec * 10**9 + f.image.header.stamp.nanosec for f in received]
    assert stamps == sorted(stamps) and len(set(stamps)) == 6  # six distinct frames
    infos = probe.subscribe(CameraInfo, "/camera/camera_info",
                            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    info = infos.wait(1)[0]  # subscribed late: TRANSIENT_LOCAL replays it
    assert (info.width, info.height, info.distortion_model) == (160, 120, "plumb_bob")
    np.testing.assert_array_equal(info.k.reshape(3, 3), K)
    np.testing.assert_array_equal(info.d, [-0.1, 0.02, 0.001, -0.002, 0.0])


@pytest.mark.skipif(TLSIMU is None, reason="TLSimu.cti needs the genicam2 wheel (pip install genicam2)")
def test_tlsimu_software_trigger_one_frame_per_trigger(spawn_node, probe):
    frames = probe.subscribe(FringeFrame, "/camera/image_raw")
    trigger_pub = probe.publisher(Trigger, "/projector/trigger")
    node = spawn_node(NODE, "--ros-args", "-p", f"cti:={TLSIMU}", "-p", "serial:=SN_InterfaceA_0", "-p",
                      "trigger_mode:=software", *SMALL, *FAST)
    assert node.wait_for_stderr("camera EMVA_D TLSimuMono serial SN_InterfaceA_0: 160x120 Mono8, trigger mode "
                                "software", timeout=20)
    assert trigger_pub.wait_for_subscriptions(1, timeout_sec=10)
    frames.wait_for_publishers(1)  # the camera's frames reach the probe before the first Trigger
    sent = triggers(9, 5)
    publish_spaced(trigger_pub, sent, gap_s=0.01)
    received = frames.wait(5, timeout=10)
    assert [f.trigger for f in received] == sent
    assert all(f.image.to_array().shape == (120, 160) for f in received)


def test_camera_timeout_is_logged_and_reported_once_per_scan(spawn_node, probe):
    status = probe.subscribe(ScanStatus, "/scanner/status")
    trigger_pub = probe.publisher(Trigger, "/projector/trigger")
    node = spawn_node(NODE, "--ros-args", "-p", "trigger_mode:=free-running", "-p", "frame_rate_hz:=1.0",
                      "-p", "frame_timeout_s:=0.1", *SMALL, *FAST)  # one frame a second: most Triggers time out
    assert node.wait_for_stderr("trigger mode free-running", timeout=20)
    assert trigger_pub.wait_for_subscriptions(1, timeout_sec=10)
    publish_spaced(trigger_pub, triggers(7, 4) + triggers(8, 4), gap_s=0.01)
    reports = status.wait(2, timeout=10)
    assert [(s.sequence_id, s.level, s.state, s.frames_expected) for s in reports] == [
        (7, ScanStatus.ERROR, "failed", 4), (8, ScanStatus.ERROR, "failed", 4)]
    assert "of scan 7: no frame within 0.100 s of the trigger (free-running)" in reports[0].reason
    assert reports[0].reason.startswith("camera: pattern ") and reports[0].node == "/camera"
    assert node.wait_for_stderr("camera timeout: pattern ")
    assert len(status.messages) == 2 and node.proc.poll() is None  # once per scan; the node stays up


def test_missing_producer_reconnect_loop_then_camera_appears(spawn_node, probe, tmp_path):
    cti = tmp_path / "vendor" / "viky.cti"
    status = probe.subscribe(ScanStatus, "/scanner/status")
    frames = probe.subscribe(FringeFrame, "/camera/image_raw")
    trigger_pub = probe.publisher(Trigger, "/projector/trigger")
    node = spawn_node(NODE, "--ros-args", "-p", f"cti:={cti}", "-p", "trigger_mode:=free-running",
                      "-p", "frame_rate_hz:=100.0", *SMALL, *FAST)
    assert node.wait_for_stderr("retrying in 0.40 s (attempt 3)", timeout=20)
    assert f"camera: GenTL producer {cti} does not exist (is the camera vendor's SDK installed?); retrying in " \
           "0.10 s (attempt 1)" in node.stderr
    assert trigger_pub.wait_for_subscriptions(1, timeout_sec=10)
    trigger_pub.publish(triggers(1, 2)[0])  # while no camera: failed at once, with the reason
    failed = status.wait(1, timeout=10)[0]
    assert failed.sequence_id == 1 and "does not exist" in failed.reason and "(reconnecting)" in failed.reason
    cti.parent.mkdir()
    os.symlink(VIKY, cti)  # the camera (its producer) appears
    assert node.wait_for_stderr("camera Machine Vision Games Ltd. Viky serial 0", timeout=10)
    sent = triggers(2, 3)
    publish_spaced(trigger_pub, sent)
    assert [f.trigger for f in frames.wait(3, timeout=10)] == sent
    assert node.proc.poll() is None


@pytest.mark.parametrize("params, message", [
    (["trigger_mode:=sometimes"], "trigger_mode must be one of hardware, software, free-running; got 'sometimes'"),
    (["rig:=/nonexistent/rig.yaml"], "parameter rig: /nonexistent/rig.yaml: no such rig file"),
])
def test_bad_parameters_exit_with_code_2_naming_them(spawn_node, params, message):
    args = [arg for param in params for arg in ("-p", param)]
    node = spawn_node(NODE, "--ros-args", *args)
    assert node.wait(timeout=20) == 2
    assert message in node.stderr


def _segments_mapped(pid: int, label: str) -> int:
    """Shared-memory segments of ``label`` the process maps (each segment of its pool is one memfd mapping)."""
    with open(f"/proc/{pid}/maps") as maps:
        return sum(f"memfd:{label}" in line for line in maps)


def test_viky_frames_are_copied_once_into_loaned_segments_and_dropped_ones_go_back(spawn_node, probe):
    frames = probe.subscribe(FringeFrame, "/camera/image_raw")
    trigger_pub = probe.publisher(Trigger, "/projector/trigger")
    # 160x120 mono8 (19 kB) through shared memory; free-running at 100 Hz: most frames meet no Trigger and are let go
    node = spawn_node(NODE, "--ros-args", "-p", "trigger_mode:=free-running", "-p", "frame_rate_hz:=100.0",
                      "-p", "serial:=1", *SMALL, *FAST, env={"DPTPU_SHM_MIN_BYTES": "1024"})
    assert node.wait_for_stderr("trigger mode free-running", timeout=20)
    assert trigger_pub.wait_for_subscriptions(1, timeout_sec=10)
    frames.wait_for_publishers(1)
    sent = triggers(4, 6)
    publish_spaced(trigger_pub, sent)
    received = frames.wait(6, timeout=10)
    assert [f.trigger for f in received] == sent
    for frame in received:
        image = frame.image.to_array()
        assert is_shared(image) and np.count_nonzero(image == 0) == 400  # viky's 20x20 square, in a segment
    time.sleep(1.0)  # ~100 more frames copied out and let go, unpublished
    # the frames let go went back to the pool: a few segments (the 6 the probe holds, one in hand), not one a frame
    mapped = _segments_mapped(node.proc.pid, "dptpu:camera:image_raw")
    assert mapped <= 12
