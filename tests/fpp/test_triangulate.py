import numpy as np
import pytest

from dptpu.fpp.distortion import distort, normalized_to_pixels
from dptpu.fpp.triangulate import Triangulator, projector_coordinate, triangulate_reference
from tests.fpp.rig_fixtures import synthetic_rig


def project(device, points):
    """World points (..., 3) -> distorted pixels (..., 2) of ``device``."""
    local = points @ device.R.T + device.T
    return normalized_to_pixels(distort(local[..., :2] / local[..., 2:3], device.dist), device.K)


def scene_points(triangulator, depth_mm):
    """World points seen by every camera pixel at the given depths (H, W) along the undistorted rays."""
    rays = triangulator.rays
    t = depth_mm / rays[..., 2]
    return triangulator.origin + t[..., None] * rays


@pytest.mark.parametrize("axis", ["x", "y"])
def test_triangulation_recovers_points_through_both_distortions(axis):
    rig = synthetic_rig(baseline=axis)
    tri = Triangulator(rig, axis=axis)
    v, u = np.mgrid[0:480, 0:640]
    depth = 800 + 40 * np.sin(u / 90.0) + 60 * (v > 240)  # a wavy surface with a 60 mm step
    truth = scene_points(tri, depth)
    coord = project(rig.projector, truth)[..., 0 if axis == "x" else 1]
    points = tri.points(coord)
    assert np.max(np.abs(points - truth)) < 1e-6


def test_vectorized_triangulation_equals_per_pixel_solve():
    rig = synthetic_rig()
    tri = Triangulator(rig)
    rng = np.random.default_rng(0)
    coord = rng.uniform(150, 400, size=tri.shape)
    points = tri.points(coord)
    rows = rng.integers(0, 480, 300)
    cols = rng.integers(0, 640, 300)
    reference = triangulate_reference(rig, np.stack([cols, rows], axis=1).astype(float), coord[rows, cols])
    assert np.max(np.abs(points[rows, cols] - reference)) < 1e-6  # mm


def test_pinhole_triangulation_equals_per_pixel_solve_without_distortion():
    rig = synthetic_rig(distortion=False)
    tri = Triangulator(rig, distortion=False)
    coord = np.full(tri.shape, 456.0)
    rows, cols = np.array([0, 100, 479]), np.array([0, 320, 639])
    reference = triangulate_reference(rig, np.stack([cols, rows], 1).astype(float), coord[rows, cols],
                                      distortion=False)
    assert np.max(np.abs(tri.points(coord)[rows, cols] - reference)) < 1e-6


def test_convention_projector_coordinate_from_phase():
    # phi = 2 pi f x_p / W: 96 periods over 912 px -> 9.5 px per period, phase 0 at column 0.
    phase = np.array([0.0, 2 * np.pi, 2 * np.pi * 96, np.nan])
    np.testing.assert_allclose(projector_coordinate(phase, 96, 912), [0.0, 9.5, 912.0, np.nan])


def test_convention_depth_increases_with_projector_column_for_a_toed_in_projector():
    # Projector 170 mm to the camera's right (+x), turned towards the camera axis: a point further away along
    # the central camera ray lands further right on the projector.
    rig = synthetic_rig(distortion=False)
    tri = Triangulator(rig, distortion=False)
    near, far = tri.points(np.full(tri.shape, 250.0)), tri.points(np.full(tri.shape, 270.0))
    assert far[240, 320, 2] > near[240, 320, 2] > 0


def test_nan_coordinates_give_nan_points_and_wrong_shape_is_refused():
    tri = Triangulator(synthetic_rig(camera_size=(64, 48)))
    coord = np.full((48, 64), 450.0)
    coord[3, 4] = np.nan
    points = tri.points(coord)
    assert np.isnan(points[3, 4]).all() and np.isfinite(points[3, 5]).all()
    with pytest.raises(ValueError, match=r"camera's shape \(48, 64\); got \(480, 640\)"):
        tri.points(np.zeros((480, 640)))
    with pytest.raises(ValueError, match="frequency must be a positive"):
        projector_coordinate(coord, 0, 912)
