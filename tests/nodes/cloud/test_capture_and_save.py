"""The cloud node's ~/capture_and_save: phase -> unwrap -> cloud in one harness (real sockets), then the service
writes the last scan's cloud (PLY and PCD, metres or millimetres, every field the node publishes) and its frames as a
dptpu-capture/1 folder that reads back."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.calibration import load_rig, save_rig
from dptpu.fpp.capture import PhaseSequence, load_sequence_images, read_capture
from dptpu.graph import Parameter
from dptpu.graph.interfaces import Trigger as TriggerService
from dptpu.messages import CameraInfo, FringeBurst, FringeFrame, Image, PointCloud2
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode
from dptpu.nodes.plumbing import LATCHED_QOS
from dptpu.nodes.unwrap import UnwrapNode
from tests.nodes.test_cloud_scene import plane_scene


def _call(harness, client) -> object:
    future = client.call_async(TriggerService.Request())
    assert harness.spin_until(future.done, timeout_s=30.0)
    return future.result()


FREQUENCIES = (16.0, 1.0)


def _scene_and_nodes(harness, tmp_path, rig=None, **cloud_parameters):
    """The plane scene's frame stacks, and phase, unwrap and cloud nodes started for it (the cloud node given
    ``rig``, default the scene's): ``(stacks, cloud node, scene)``."""
    scene = plane_scene()
    rig_path = save_rig(rig or scene.rig, tmp_path / "rig.yaml")
    stacks = [scene.frames(f, seed=index) for index, f in enumerate(FREQUENCIES)]
    harness.start(PhaseNode, timeout_s=1.0, projector_width=912, projector_height=1140)
    harness.start(UnwrapNode, method="mf")
    cloud_node = harness.start(CloudNode, rig=str(rig_path), save_dir=str(tmp_path / "saved"), **cloud_parameters)
    return stacks, cloud_node, scene


def test_the_last_scan_is_saved_as_a_cloud_in_metres_and_a_capture_folder(tmp_path):
    import open3d as o3d

    frequencies = FREQUENCIES
    with NodeHarness() as harness:
        stacks, cloud_node, scene = _scene_and_nodes(harness, tmp_path)
        camera = harness.publisher(FringeFrame, "/camera/image_raw")
        points = harness.collect(PointCloud2, "/scanner/points")
        client = harness.probe.create_client(TriggerService, "/cloud/capture_and_save")
        harness.connect()
        # the frames go to the phase node and to the cloud node (it keeps the last scans' frames)
        assert harness.spin_until(lambda: camera.get_subscription_count() >= 2, timeout_s=15.0)
        assert harness.spin_until(client.service_is_ready, timeout_s=15.0)
        nothing = _call(harness, client)
        assert (nothing.success, nothing.message) == (False, "no scan to save yet: no cloud was published")
        for frame in fringe_frames(stacks, frequencies, sequence_id=7):
            camera.publish(frame)
        (cloud,) = harness.wait(points, 1)
        # the cloud was filled in a loaned segment; the service makes it again from what the node kept
        assert cloud_node.points_publisher.shared_count == 1
        answers = [_call(harness, client)]
        assert cloud_node.set_parameters([Parameter("save_format", value="pcd")])[0].successful  # applies at once
        answers.append(_call(harness, client))
        assert not cloud_node.set_parameters([Parameter("save_units", value="inch")])[0].successful
        assert cloud_node.set_parameters([Parameter("save_units", value="mm"),
                                          Parameter("save_dir", value=str(tmp_path / "mm"))])[0].successful
        in_mm = _call(harness, client)
    folder = tmp_path / "saved" / "scan_00000007"
    xyz = cloud.to_array(["x", "y", "z"]).reshape(-1, 3)
    for answer, save_format in zip(answers, ("ply", "pcd")):
        assert answer.success, answer.message
        assert answer.message == (f"saved scan 7: {folder / f'cloud.{save_format}'} (19200 points, metres) and "
                                  f"{folder / 'capture'} (8 frames)")
        written = o3d.t.io.read_point_cloud(str(folder / f"cloud.{save_format}")).point
        finite = np.isfinite(xyz).all(axis=1)
        assert np.abs(written.positions.numpy() - xyz[finite]).max() < 1e-6  # (M, 3) m
        # every field of the published cloud (before: x y z and grey colours only)
        names = [f.name for f in cloud.fields]
        assert names == ["x", "y", "z", "intensity", "modulation", "confidence", "normal_x", "normal_y", "normal_z"]
        normals = cloud.to_array(["normal_x", "normal_y", "normal_z"]).reshape(-1, 3)[finite]
        np.testing.assert_array_equal(written.normals.numpy(), normals)
        for name in ("intensity", "modulation", "confidence"):
            np.testing.assert_array_equal(written[name].numpy()[:, 0], cloud.to_array([name]).reshape(-1)[finite])
        assert np.isfinite(written.confidence.numpy()).all() and np.isfinite(written.modulation.numpy()).all()
    assert in_mm.message == (f"saved scan 7: {tmp_path / 'mm' / 'scan_00000007' / 'cloud.pcd'} (19200 points, "
                             f"millimetres) and {tmp_path / 'mm' / 'scan_00000007' / 'capture'} (8 frames)")
    in_mm_points = o3d.t.io.read_point_cloud(str(tmp_path / "mm" / "scan_00000007" / "cloud.pcd")).point.positions
    assert np.abs(in_mm_points.numpy() - 1000.0 * xyz[finite]).max() < 1e-3
    remade = cloud_node.capture._last[1]()  # every field, bit for bit the published cloud
    assert remade.fields == cloud.fields and np.array_equal(remade.to_array(), cloud.to_array(), equal_nan=True)
    assert cloud_node.capture.saved == 3
    capture = read_capture(folder / "capture")
    assert [(s.frequency, s.steps) for s in capture.sequences if isinstance(s, PhaseSequence)] == [(16.0, 4),
                                                                                                   (1.0, 4)]
    for sequence, stack in zip(capture.sequences, stacks):
        assert np.array_equal(load_sequence_images(capture, sequence), stack)  # the frames, bit for bit
    assert (capture.projector_size, capture.fringe_axis, capture.phase_shift_sign) == ((912, 1140), "x", -1)
    assert np.array_equal(load_rig(capture.calibration).camera.K, scene.rig.camera.K)


def test_a_bad_save_format_is_refused_naming_the_choices(tmp_path):
    rig_path = save_rig(plane_scene().rig, tmp_path / "rig.yaml")
    with NodeHarness() as harness, pytest.raises(ValueError, match="save_format"):
        harness.start(CloudNode, rig=str(rig_path), save_format="obj")


def test_a_cloud_node_taking_bursts_from_a_camera_side_sending_frames_says_where_it_listened(tmp_path):
    frequencies = FREQUENCIES
    with NodeHarness() as harness:
        stacks, cloud_node, _ = _scene_and_nodes(harness, tmp_path, frame_bursts=True)
        camera = harness.publisher(FringeFrame, "/camera/image_raw")
        bursts = harness.publisher(FringeBurst, "/camera/frame_bursts", connect=False)
        points = harness.collect(PointCloud2, "/scanner/points")
        client = harness.probe.create_client(TriggerService, "/cloud/capture_and_save")
        harness.connect()
        assert harness.spin_until(client.service_is_ready, timeout_s=15.0)
        frames = fringe_frames(stacks, frequencies, sequence_id=3)
        for frame in frames:
            camera.publish(frame)
        harness.wait(points, 1)
        answer = _call(harness, client)
        # a burst that is no camera frame (an 8UC1 image) is logged, not kept
        assert harness.spin_until(lambda: bursts.get_subscription_count() >= 1, timeout_s=15.0)
        odd = FringeBurst(image=Image.from_array(stacks[0][0], "8UC1"), triggers=[frames[0].trigger])
        bursts.publish(odd)
        harness.spin_for(0.5)
        assert cloud_node.capture.frames.frames(3) == []
    assert answer.success and answer.message.endswith(
        "; no frames of it were received on /camera/frame_bursts (frame_bursts:=true: the camera side must publish "
        "there), so no capture folder"), answer.message


def test_the_capture_holds_the_camera_the_cloud_was_triangulated_with(tmp_path):
    """The rig file's camera at another size than the frames (a launch's size:=), the frames' camera from
    CameraInfo: the capture's calibration is the camera of the frames, so the capture replays as it was scanned."""
    import dataclasses

    scene = plane_scene()
    big = dataclasses.replace(scene.rig, camera=dataclasses.replace(
        scene.rig.camera, K=scene.rig.camera.K * np.array([[2, 1, 2], [1, 2, 2], [1, 1, 1]]), size=(320, 240)))
    with NodeHarness() as harness:
        stacks, cloud_node, _ = _scene_and_nodes(harness, tmp_path, rig=big, use_camera_info=True)
        camera = harness.publisher(FringeFrame, "/camera/image_raw")
        info = harness.publisher(CameraInfo, "/camera/camera_info", LATCHED_QOS, connect=False)
        points = harness.collect(PointCloud2, "/scanner/points")
        client = harness.probe.create_client(TriggerService, "/cloud/capture_and_save")
        harness.connect()
        info.publish(CameraInfo.from_intrinsics(scene.rig.camera.K, scene.rig.camera.dist, 160, 120))
        assert harness.spin_until(lambda: cloud_node.rig.camera.size == (160, 120), timeout_s=15.0)
        for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=5):
            camera.publish(frame)
        harness.wait(points, 1)
        answer = _call(harness, client)
    assert answer.success, answer.message
    saved = load_rig(read_capture(tmp_path / "saved" / "scan_00000005" / "capture").calibration)
    assert saved.camera.size == (160, 120)
    np.testing.assert_allclose(saved.camera.K, scene.rig.camera.K)
    np.testing.assert_allclose(saved.projector.K, scene.rig.projector.K)  # the rest is the rig file's
    assert load_rig(tmp_path / "saved" / "scan_00000005" / "calibration.yaml").camera.size == (160, 120)
