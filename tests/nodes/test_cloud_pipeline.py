"""phase -> unwrap -> cloud in one harness: fringe frames of the analytic plane in, its points out; a shadowed
rectangle (no fringe modulation) comes out as NaN holes exactly.

Bound, from the phase noise of this scene (RMS 0.005 rad at f = 16, test_phase_node.py): the projector
coordinate is off by 0.005 * 912 / (2*pi*16) = 0.045 px RMS, and at 850 mm with a 170 mm baseline one
projector pixel is about z**2 / (b * f_p) = 850**2 / (170 * 1730) = 2.5 mm of depth, so about 0.11 mm RMS.
Measured: depth RMS 0.10 mm, max 0.42 mm over 19,200 points; we require RMS < 0.25 mm and max < 1 mm.
"""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.calibration import save_rig
from dptpu.messages import FringeFrame, PointCloud2, ScanStatus
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode
from dptpu.nodes.unwrap import UnwrapNode
from tests.nodes.test_cloud_scene import plane_scene

DEPTH_RMS_BOUND_M = 0.25e-3
DEPTH_MAX_BOUND_M = 1.0e-3


@pytest.mark.parametrize("method, frequencies", [("mf", (16.0, 1.0)), ("nt", (16.0, 15.0))])
def test_frames_of_the_plane_become_its_points(tmp_path, method, frequencies):
    scene = plane_scene()
    rig_path = save_rig(scene.rig, tmp_path / "rig.yaml")
    with NodeHarness() as harness:
        harness.start(PhaseNode, timeout_s=1.0, projector_width=912, projector_height=1140)
        harness.start(UnwrapNode, method=method)
        cloud_node = harness.start(CloudNode, rig=str(rig_path), normal_window_px=5,
                                   intensity_wait_s=10.0)  # the texture is checked: never published without it
        camera = harness.publisher(FringeFrame, "/camera/image_raw")
        points = harness.collect(PointCloud2, "/scanner/points")
        status = harness.collect(ScanStatus, "/scanner/status")
        harness.connect()
        # the cloud node's side images (the phase node's texture, the unwrap node's modulation) are connected too:
        # without a publisher a scan does not wait for its image
        assert harness.spin_until(lambda: all(sub.get_publisher_count() for sub in
                                              cloud_node._side_subscriptions.values()), timeout_s=15.0)
        shadow = np.zeros(scene.lit.shape, bool)
        shadow[30:50, 100:140] = True  # the projector does not reach there: no fringes, no points
        stacks = [scene.frames(f, seed=index, shadow=shadow) for index, f in enumerate(frequencies)]
        for sequence_id in (1, 2):
            for frame in fringe_frames(stacks, frequencies, sequence_id=sequence_id):
                camera.publish(frame)
        clouds = harness.wait(points, 2)
        assert [c.sequence_id for c in harness.wait(status, 6) if c.node == "/cloud"] == [1, 2]
    assert cloud_node.scans_published == 2
    xyz = clouds[1].to_array(["x", "y", "z"])  # (H, W, 3) metres, camera optical frame
    assert np.array_equal(np.isnan(xyz).any(axis=-1), shadow)  # holes exactly where the shadow is
    xyz, truth = xyz[~shadow], scene.points_mm[~shadow] * 1e-3  # (M, 3)
    depth_error = xyz[..., 2] - truth[..., 2]
    assert np.sqrt(np.mean(depth_error**2)) < DEPTH_RMS_BOUND_M
    assert np.abs(depth_error).max() < DEPTH_MAX_BOUND_M
    # every point lies on its pixel's ray: the lateral error is the depth error scaled by x/z, y/z
    assert np.abs(xyz[..., :2] - truth[..., :2] * (xyz[..., 2:] / truth[..., 2:])).max() < 1e-6
    # and the points fit the plane n . X = d
    normal = np.array([0.12, -0.08, -1.0]) / np.linalg.norm([0.12, -0.08, -1.0])
    assert np.abs(xyz @ normal - normal @ [0.0, 0.0, 0.85]).max() < DEPTH_MAX_BOUND_M
    modulation = clouds[1].to_array(["modulation"])
    assert 70 < float(np.median(modulation)) < 90  # fringe modulation of f = 16, DN
    # the texture (the phase node's mean intensity A of Eq. (2)) is the scene's albedo as rendered:
    # 8 + 0.9 * albedo * 255 * offset 0.5 DN (tests/conftest.py), albedo 0.8 lit and 0.01 in the shadow; the noise
    # of 0.5 DN and the frames' rounding average over 8 frames to 0.2 DN RMS (measured max 0.82-0.93 DN off over
    # 19,200 pixels, 4.5 sigma)
    texture = clouds[1].to_array(["intensity"])[..., 0]
    expected = 8.0 + 0.9 * np.where(shadow, 0.01, 0.8) * 255 * 0.5
    assert np.abs(texture - expected).max() < 1.5
    # the normals of the plane from these noisy points (depth RMS 0.1 mm, 2.5 mm apart: one central difference
    # tilts by about 1.6 deg, so 5 x 5 windows here), toward the camera: measured median 0.53, 90th percentile
    # 0.98 deg
    normals = clouds[1].to_array(["normal_x", "normal_y", "normal_z"])[~shadow].astype(np.float64)  # (M, 3)
    angle_deg = np.degrees(np.arccos(np.clip(normals @ normal, -1.0, 1.0)))
    assert np.median(angle_deg) < 1.0 and np.percentile(angle_deg, 90) < 1.5
