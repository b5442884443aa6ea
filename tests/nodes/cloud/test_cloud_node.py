"""The cloud node in the in-process harness: AbsolutePhase of the analytic plane in, PointCloud2 and depth out."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from dptpu.fpp.calibration import DeviceModel, Rig, save_rig
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import (
    AbsolutePhase,
    CameraInfo,
    Header,
    Image,
    PointCloud2,
    ScanStatus,
    Time,
)
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.cloud.node import FIELDS
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.scan_monitor.node import _STAMP_MATCH_NS
from tests.nodes.test_cloud_scene import PLANE_NORMAL, plane_scene

STAMP = Time.from_ns(1_700_000_000_000_000_000)
# Exact phase in, float32 on the wire (100 rad in float32: 4e-6 rad = 4e-5 projector px, 0.1 um of depth at
# 850 mm) and float32 points (0.05 um at 0.85 m). Measured: 0.07 um, both world frames.
MAX_POINT_ERROR_M = 1e-6


@pytest.fixture(scope="module")
def scene():
    return plane_scene()


@pytest.fixture
def harness():
    with NodeHarness() as harness:
        yield harness


def absolute_phase(scene, *, frequency=16.0, sequence_id=1, shape=None, projector=(912, 1140)):
    psi = scene.absolute_phase(frequency).astype(np.float32)
    if shape is not None:
        psi = np.zeros(shape, np.float32)
    valid = np.ones(psi.shape, bool)
    return AbsolutePhase(header=Header(stamp=STAMP, frame_id="camera"), sequence_id=sequence_id, frequency=frequency,
                         fringe_axis="x", projector_width=projector[0], projector_height=projector[1],
                         absolute_phase=psi, fringe_order=np.floor(psi / (2 * np.pi)).astype(np.int32), valid=valid,
                         reliability=np.full(psi.shape, 0.9, np.float32), method="mf")


def start(harness, rig_path, **parameters):
    node = harness.start(CloudNode, rig=str(rig_path), **parameters)
    source = harness.publisher(AbsolutePhase, "/scanner/absolute_phase")
    intensity = harness.publisher(Image, "/scanner/intensity")
    points = harness.collect(PointCloud2, "/scanner/points")
    depth = harness.collect(Image, "/scanner/depth/image")
    status = harness.collect(ScanStatus, "/scanner/status")
    harness.connect()
    return node, source, intensity, points, depth, status


@pytest.mark.parametrize("world_pose", [False, True], ids=["world=camera", "world elsewhere"])
def test_cloud_of_the_plane_is_in_the_camera_optical_frame_in_metres(harness, tmp_path, world_pose):
    scene = plane_scene(world_pose=world_pose)
    _node, source, intensity, points, depth, status = start(harness, save_rig(scene.rig, tmp_path / "rig.yaml"))
    texture_source = harness.publisher(Image, "/scanner/texture")
    depth_info = harness.collect(CameraInfo, "/scanner/depth/camera_info")
    confidence_info = harness.collect(CameraInfo, "/scanner/confidence/camera_info")
    harness.connect()
    modulation = np.linspace(10, 100, 120 * 160, dtype=np.float32).reshape(120, 160)
    texture = np.linspace(200, 20, 120 * 160, dtype=np.float32).reshape(120, 160)
    source.publish(absolute_phase(scene))  # before its side images: it waits for them (intensity_wait_s)
    intensity.publish(Image.from_array(modulation, "32FC1", header=Header(stamp=STAMP, frame_id="camera")))
    texture_source.publish(Image.from_array(texture, "32FC1", header=Header(stamp=STAMP, frame_id="camera")))
    (cloud,) = harness.wait(points, 1)
    assert (cloud.height, cloud.width, cloud.is_dense) == (120, 160, False)
    assert [f.name for f in cloud.fields] == list(FIELDS) == [
        "x", "y", "z", "intensity", "modulation", "confidence", "normal_x", "normal_y", "normal_z"]
    assert cloud.point_step == 36
    assert (cloud.header.frame_id, cloud.header.stamp) == ("scanner_optical_frame", STAMP)
    xyz = cloud.to_array(["x", "y", "z"])  # (H, W, 3) float32
    assert xyz.dtype == np.float32
    assert np.abs(xyz - scene.points_mm * 1e-3).max() < MAX_POINT_ERROR_M
    assert np.array_equal(cloud.to_array(["intensity"])[..., 0], texture)
    assert np.array_equal(cloud.to_array(["modulation"])[..., 0], modulation)
    assert np.all(cloud.to_array(["confidence"]) == np.float32(0.9))
    normals = cloud.to_array(["normal_x", "normal_y", "normal_z"]).astype(np.float64)  # (H, W, 3)
    # the plane's normal (0.12, -0.08, -1), toward the camera; exact points: within 0.05 deg (measured 0.03)
    angle_deg = np.degrees(np.arccos(np.clip(normals @ PLANE_NORMAL, -1.0, 1.0)))
    assert angle_deg.max() < 0.05
    (image,) = harness.wait(depth, 1)
    assert image.encoding == "32FC1" and image.header.frame_id == "scanner_optical_frame"
    assert np.array_equal(image.to_array(), xyz[..., 2])
    # the sibling camera_info of each image (ROS image_transport): same header, the rig's camera
    for info in (harness.wait(depth_info, 1)[0], harness.wait(confidence_info, 1)[0]):
        assert info.header == image.header and (info.width, info.height) == (160, 120)
        assert np.array_equal(np.reshape(info.k, (3, 3)), scene.rig.camera.K)
    (ok,) = harness.wait(status, 1)
    assert (ok.level, ok.state, ok.valid_pixels, ok.total_pixels) == (ScanStatus.OK, "done", 19200, 19200)
    # the contract the scan monitor names a cloud's scan by (docs/nodes.md): status stamp - duration = scan stamp,
    # to float64's rounding of the duration in ns (measured 0-18 ns for the 3 years since STAMP; exact below 104
    # days), well within the monitor's match tolerance
    assert abs(ok.header.stamp.to_ns() - round(ok.duration_s * 1e9) - STAMP.to_ns()) <= _STAMP_MATCH_NS
    assert ok.sequence_id == 1


def test_invalid_pixels_are_nan_and_the_frame_id_is_a_parameter(harness, tmp_path, scene):
    node, source, _intensity, points, _depth, status = start(harness, save_rig(scene.rig, tmp_path / "rig.yaml"),
                                                           frame_id="tool0_scanner")
    msg = absolute_phase(scene)
    msg.valid[:, :40] = False
    msg.absolute_phase[7, 50:53] = [np.nan, np.inf, -np.inf]  # marked valid: made invalid and counted
    source.publish(msg)
    (cloud,) = harness.wait(points, 1)
    xyz = cloud.to_array(["x", "y", "z"])
    assert np.isnan(xyz[:, :40]).all() and np.isnan(xyz[7, 50:53]).all()
    assert np.isfinite(xyz[:, 40:]).sum() == 3 * (120 * 120 - 3)
    assert np.isnan(cloud.to_array(["intensity", "modulation"])).all()  # no side image of scan 1 was seen
    assert cloud.header.frame_id == "tool0_scanner"
    (warn,) = harness.wait(status, 1)
    assert warn.level == ScanStatus.WARN and warn.reason == (
        "3 pixels marked valid had a non-finite absolute phase; treated as invalid; "
        "no texture image of scan 1 seen: intensity NaN; no modulation image of scan 1 seen: modulation NaN")
    assert warn.valid_pixels == 120 * 120 - 3 and node.pixels_nan == 3


def test_inconsistent_scans_are_reported_and_the_node_goes_on(harness, tmp_path, scene):
    node, source, _intensity, points, _depth, status = start(harness, save_rig(scene.rig, tmp_path / "rig.yaml"))
    source.publish(absolute_phase(scene, sequence_id=1, shape=(60, 80)))
    source.publish(absolute_phase(scene, sequence_id=2, projector=(1280, 800)))
    source.publish(absolute_phase(scene, sequence_id=3))
    (_cloud,) = harness.wait(points, 1)
    failed = [s for s in harness.wait(status, 3) if s.state == "failed"]
    assert [s.reason for s in failed] == [
        "cannot triangulate scan 1: absolute_phase is 80x60 pixels; the rig's camera is 160x120",
        "cannot triangulate scan 2: the scan's projector is 1280x800; the rig's is 912x1140"]
    assert node.scans_rejected == 2 and node.scans_published == 1


def test_camera_info_supplies_the_camera_intrinsics(harness, tmp_path, scene):
    true_camera = scene.rig.camera
    wrong = DeviceModel(K=true_camera.K * [[1.1], [1.1], [1]], dist=np.zeros(5), R=true_camera.R, T=true_camera.T,
                        size=(320, 240))
    rig_path = save_rig(Rig(camera=wrong, projector=scene.rig.projector, units="mm"), tmp_path / "rig.yaml")
    node = harness.start(CloudNode, rig=str(rig_path), use_camera_info=True)
    info = harness.publisher(CameraInfo, "/camera/camera_info",
                             QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    source = harness.publisher(AbsolutePhase, "/scanner/absolute_phase")
    points = harness.collect(PointCloud2, "/scanner/points")
    harness.connect()
    info.publish(CameraInfo.from_intrinsics(true_camera.K, true_camera.dist, 160, 120))
    assert harness.spin_until(lambda: node.rig.camera.size == (160, 120))
    source.publish(absolute_phase(scene))
    (cloud,) = harness.wait(points, 1)
    assert np.abs(cloud.to_array(["x", "y", "z"]) - scene.points_mm * 1e-3).max() < MAX_POINT_ERROR_M
    # the same camera announced again under a new frame (param set /sim frame_id): the tables are kept, not rebuilt
    # (a 640x480 rig's tables take a second); another camera, in order after it, gets new ones
    built, build = [], node._triangulator
    node._triangulator = lambda axis: (built.append(axis), build(axis))[1]
    info.publish(CameraInfo.from_intrinsics(true_camera.K, true_camera.dist, 160, 120,
                                            header=Header(frame_id="left_camera_optical_frame")))
    info.publish(CameraInfo.from_intrinsics(true_camera.K * [[1.001], [1.001], [1]], true_camera.dist, 160, 120))
    assert harness.spin_until(lambda: node.rig.camera.K[0, 0] == pytest.approx(true_camera.K[0, 0] * 1.001))
    assert built == ["x"]


def test_a_scan_before_the_first_camera_info_waits_for_it_or_fails_with_the_reason(harness, tmp_path, scene):
    true_camera = scene.rig.camera
    wrong = DeviceModel(K=true_camera.K * [[2], [2], [1]], dist=np.zeros(5), R=true_camera.R, T=true_camera.T,
                        size=(320, 240))  # the rig file's camera: another size than the frames
    rig_path = save_rig(Rig(camera=wrong, projector=scene.rig.projector, units="mm"), tmp_path / "rig.yaml")
    node = harness.start(CloudNode, rig=str(rig_path), use_camera_info=True, camera_info_wait_s=0.5)
    info = harness.publisher(CameraInfo, "/camera/camera_info",
                             QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    source = harness.publisher(AbsolutePhase, "/scanner/absolute_phase")
    points = harness.collect(PointCloud2, "/scanner/points")
    status = harness.collect(ScanStatus, "/scanner/status")
    harness.connect()
    source.publish(absolute_phase(scene, sequence_id=1))  # no CameraInfo yet: waits 0.5 s, then fails
    (failed,) = harness.wait(status, 1)
    assert failed.state == "failed" and failed.reason == (
        "cannot triangulate scan 1: no CameraInfo on /camera/camera_info within 0.5 s")
    source.publish(absolute_phase(scene, sequence_id=2))  # waits, and is triangulated once the CameraInfo is in
    info.publish(CameraInfo.from_intrinsics(true_camera.K, true_camera.dist, 160, 120))
    (cloud,) = harness.wait(points, 1)
    assert np.abs(cloud.to_array(["x", "y", "z"]) - scene.points_mm * 1e-3).max() < MAX_POINT_ERROR_M
    assert node.scans_rejected == 1 and node.scans_published == 1


def test_ply_snapshots_every_nth_scan_through_open3d(harness, tmp_path, scene):
    import open3d as o3d

    node, source, _intensity, points, _depth, _status = start(harness, save_rig(scene.rig, tmp_path / "rig.yaml"),
                                                           ply_dir=str(tmp_path / "ply"), ply_every=2)
    for sequence_id in (1, 2, 3):
        msg = absolute_phase(scene, sequence_id=sequence_id)
        msg.valid[:20] = False
        source.publish(msg)
    harness.wait(points, 3)
    assert sorted(p.name for p in (tmp_path / "ply").iterdir()) == ["scan_00000001.ply", "scan_00000003.ply"]
    cloud = o3d.io.read_point_cloud(str(tmp_path / "ply" / "scan_00000003.ply"))
    read = np.asarray(cloud.points)
    assert read.shape == (100 * 160, 3) and node.ply_written == 2
    assert np.abs(read - scene.points_mm[20:].reshape(-1, 3) * 1e-3).max() < MAX_POINT_ERROR_M


def test_missing_rig_is_refused_with_what_to_do(harness, tmp_path):
    with pytest.raises(ValueError, match="parameter rig must name a dptpu-rig/1 calibration file"):
        harness.start(CloudNode)
    with pytest.raises(FileNotFoundError, match="no such rig file"):
        harness.start(CloudNode, rig=str(tmp_path / "absent.yaml"))


def test_outside_rig_scan_drops_low_confidence_and_depth_edges_and_publishes_the_confidence(harness, tmp_path):
    """A 12-step heterodyne scan of spheres before a plane, rendered with mixed pixels at the depth edges
    (tests/mixed_pixel_rigs.py): the published points lie on the true surfaces, what was dropped is counted."""
    from dptpu.fpp import phase, tpu
    from tests.mixed_pixel_rigs import PROJECTOR_SIZE, OutsideRig, default_scene, render

    outside = OutsideRig(camera_focal_px=500.0, baseline_mm=100.0, toe_in_deg=8.0, distance_mm=450.0)
    capture = render(outside, default_scene(outside, seed=1), [96.0, 95.0], steps=12, noise_dn=1.5693, seed=1)
    maps = [phase.wrapped_phase(capture.frames[f]) for f in (96.0, 95.0)]
    result = tpu.unwrap_heterodyne([m.phase for m in maps], [96.0, 95.0], valid=maps[0].modulation >= 5.1)
    with np.errstate(invalid="ignore"):
        valid = result.valid & (result.absolute_phase >= 0) & (result.absolute_phase < 2 * np.pi * 96.0)
    scan = AbsolutePhase(header=Header(stamp=STAMP, frame_id="camera"), sequence_id=3, frequency=96.0,
                         fringe_axis="x", projector_width=PROJECTOR_SIZE[0], projector_height=PROJECTOR_SIZE[1],
                         absolute_phase=np.where(valid, result.absolute_phase, np.nan).astype(np.float32),
                         fringe_order=result.fringe_order.astype(np.int32), valid=valid,
                         reliability=np.where(valid, result.reliability, 0).astype(np.float32), method="heterodyne")
    node, source, intensity, points, _depth, status = start(harness, save_rig(capture.rig, tmp_path / "rig.yaml"),
                                                             distortion=False)
    confidence = harness.collect(Image, "/scanner/confidence/image")
    harness.connect()
    intensity.publish(Image.from_array(maps[0].modulation.astype(np.float32), "32FC1",
                                       header=Header(stamp=STAMP, frame_id="camera")))
    source.publish(scan)
    (cloud,) = harness.wait(points, 1)
    (image,) = harness.wait(confidence, 1)
    (done,) = harness.wait(status, 1)
    assert image.header.stamp == cloud.header.stamp == STAMP and image.encoding == "32FC1"
    quality = cloud.to_array(["confidence"])[..., 0]
    assert np.array_equal(image.to_array(), quality)
    xyz_mm = cloud.to_array(["x", "y", "z"]).astype(np.float64) * 1000.0  # camera frame = world frame here
    published = np.isfinite(xyz_mm[..., 2])
    assert np.all(quality[published] >= 0.2) and np.all(quality[~published] == 0)
    low = int(np.count_nonzero(valid & (scan.reliability < 0.2)))
    assert node.points_low_confidence == low and f"{low} pixels below min_confidence 0.2 dropped" in done.reason
    assert node.points_flying > 0 and node.points_modulation_dip > 0
    assert "points at depth edges dropped" in done.reason
    off = capture.scene.distance_mm(xyz_mm[published]) > 1.0
    assert off.mean() <= 0.0005  # the goal for 12-step captures: <= 0.05 % of the published points off the surface
    # measured 96.3 % of the pure pixels published: the 96/95 beat amplifies the noise 96 times, so dark pixels
    # fall below min_confidence (the network, or a heterodyne tree of smaller ratios, keeps more)
    assert np.count_nonzero(published & capture.pure) >= 0.95 * capture.pure.sum()
    # normals against the analytic surfaces (3 x 3 windows of central differences of noisy points; 96/95 heterodyne
    # amplifies the 1.6 DN noise). Measured, median / 90th percentile: plane 0.21 / 0.41 deg; the three spheres
    # (radius 14-15 mm, about 22 px) 1.34-2.04 / 3.1-4.9 deg, their curvature over the window and the noise. Since the
    # edge filter keeps the near side's last pixel (fpp.depth_edges), the spheres' rims, seen almost edge-on, are
    # published too: judged apart (a point with a neighbour unpublished has a one-sided window). Measured: inside
    # 0.95-1.07 / 2.5-2.9 deg, at the rims' 1.8-2.9 deg median (90th percentile 5-42 deg: edge-on)
    normals = cloud.to_array(["normal_x", "normal_y", "normal_z"]).astype(np.float64)[published]  # (M, 3)
    _, which = capture.scene.hit(np.zeros(3), xyz_mm[published])
    truth = capture.scene.normal(xyz_mm[published], which)
    truth *= -np.sign(np.sum(truth * xyz_mm[published], axis=-1))[:, None]  # toward the camera
    angle_deg = np.degrees(np.arccos(np.clip(np.sum(normals * truth, axis=-1), -1.0, 1.0)))
    assert np.isfinite(angle_deg).mean() > 0.99
    plane = (which == 0) & np.isfinite(angle_deg)
    assert np.median(angle_deg[plane]) < 0.5 and np.percentile(angle_deg[plane], 90) < 1.0
    inside = cv2.erode(published.astype(np.uint8), np.ones((3, 3), np.uint8))[published] > 0  # all 8 published
    for sphere in range(1, len(capture.scene.spheres) + 1):
        on = (which == sphere) & np.isfinite(angle_deg)
        assert np.median(angle_deg[on & ~inside]) < 4.0
        assert np.median(angle_deg[on & inside]) < 2.5 and np.percentile(angle_deg[on & inside], 90) < 6.0


@pytest.mark.parametrize("drop", [True, False])
def test_a_patch_one_fringe_order_off_is_dropped_as_an_island(harness, tmp_path, scene, drop):
    """A 10 x 12 pixel patch of the plane one order off (as a network's wrong patch: self-consistent, a 2 pi jump
    all around, the modulation unbroken): its points are not published, and counted; drop_order_islands false
    publishes them, 2 pi of phase off the plane."""
    node, source, intensity, points, _depth, status = start(harness, save_rig(scene.rig, tmp_path / "rig.yaml"),
                                                            drop_order_islands=drop, intensity_wait_s=5.0)
    msg = absolute_phase(scene)
    patch = np.zeros(msg.absolute_phase.shape, bool)
    patch[50:60, 70:82] = True
    msg.absolute_phase[patch] += np.float32(2 * np.pi)
    source.publish(msg)
    intensity.publish(Image.from_array(np.full(patch.shape, 60.0, np.float32), "32FC1",
                                       header=Header(stamp=STAMP, frame_id="camera")))
    (cloud,) = harness.wait(points, 1)
    z = cloud.to_array(["z"])[..., 0]
    around = np.zeros(patch.shape, bool)
    around[48:62, 68:84] = True  # the patch and the two pixels around it, beside its depth step
    if drop:
        assert np.isnan(z[patch]).all() and np.isfinite(z[~around]).all()
        # 120 less the patch's 4 corners, flying points (apart from the plane on both sides along a diagonal); its rim
        # continues the patch without a modulation dip, so the edge filter keeps it for the islands to take
        assert node.points_on_islands == 116
        (done,) = harness.wait(status, 1)
        assert f"{node.points_on_islands} points on islands of a wrong fringe order dropped" in done.reason
    else:
        inner = np.zeros(patch.shape, bool)
        inner[51:59, 71:81] = True  # the patch but its rim (beside the step: the edge filter's)
        assert np.isfinite(z[inner]).all() and np.isfinite(z[~around]).all() and node.points_on_islands == 0
        depth_step = np.nanmedian(z[inner]) - np.nanmedian(z[45:65, 90:100])
        assert abs(depth_step) > 0.01  # published one fringe period (tens of mm) off the plane
