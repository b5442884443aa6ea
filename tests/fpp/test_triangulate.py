import numpy as np
import pytest

from dptpu.fpp._ray_distortion import RayDistortion
from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.fpp.distortion import distort, normalized_to_pixels
from dptpu.fpp.triangulate import Triangulator, projector_coordinate, triangulate_reference
from tests.fpp.rig_fixtures import rotation, synthetic_rig


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


# --- fast paths against the reference formulas ------------------------------------------------------------


def with_projector_dist(rig, dist):
    p = rig.projector
    return Rig(camera=rig.camera, projector=DeviceModel(K=p.K, dist=dist, R=p.R, T=p.T, size=p.size), units=rig.units)


def moved_world(rig, R0, T0):
    """The same rig described in a world moved by ``X' = R0 X + T0`` (device frames unchanged)."""
    def move(d):
        return DeviceModel(K=d.K, dist=d.dist, R=d.R @ R0.T, T=d.T - d.R @ R0.T @ T0, size=d.size)
    return Rig(camera=move(rig.camera), projector=move(rig.projector), units=rig.units)


def wavy_coordinates(tri, axis=0):
    """Measured projector coordinates (H, W) of a wavy surface 700-900 mm away, and its world points."""
    height, width = tri.shape
    v, u = np.mgrid[0:height, 0:width]
    depth = 800 + 60 * np.sin(u / (width / 7)) + 40 * (v > height / 2)
    truth = scene_points(tri, depth)
    return project(tri.rig.projector, truth)[..., axis], truth


@pytest.mark.parametrize("dist", [[-0.05, 1.5, 0.001, 0.001, 0.0],  # the fixture's: degree 5
                                  [-0.05, 6.3, 0.001, 0.001, -20.0],  # strong, with k3: degree 7
                                  [0.0, 0.0, 0.002, -0.001, 0.0]])  # tangential only: degree 3
def test_newton_triangulation_equals_the_converged_fixed_point(dist):
    # The textbook fixed point, run to convergence per pixel (40 iterations), is the reference.
    rig = with_projector_dist(synthetic_rig(camera_size=(160, 120)), dist)
    tri = Triangulator(rig)
    coord, truth = wavy_coordinates(tri)
    points = tri.points(coord)
    assert tri._projector_distortion.degree == {0.0: 3, 1.5: 5, 6.3: 7}[dist[1]]
    assert np.max(np.abs(points - truth)) < 1e-8  # mm
    rng = np.random.default_rng(0)
    rows, cols = rng.integers(0, 120, 60), rng.integers(0, 160, 60)
    reference = triangulate_reference(rig, np.stack([cols, rows], 1).astype(float), coord[rows, cols],
                                      projector_iterations=40)
    assert np.max(np.abs(points[rows, cols] - reference)) < 1e-8


def test_ray_polynomial_is_the_distortion_model_and_newton_inverts_it():
    rig = with_projector_dist(synthetic_rig(camera_size=(160, 120)), [-0.05, 6.3, 0.001, 0.001, -20.0])
    tri = Triangulator(rig)
    model = RayDistortion(rig.projector, tri.origin, tri.rays, axis=0)
    assert model.degree == 7 and model.kappa > 0
    assert 1e-3 < model.guess_error_px < 5 and model.float32_passes == 1  # strong: a float32 pass first
    rng = np.random.default_rng(1)
    ideal_px = rng.uniform(-50, 962, tri.shape)
    u = (ideal_px - model.mid_px) / model.half_px
    polynomial = sum(c * u**k for k, c in enumerate(model.coefficients))
    exact = model.measured(ideal_px)
    assert np.max(np.abs(polynomial - exact)) < 1e-9  # px: exact interpolation of a degree-7 polynomial
    assert np.max(np.abs(model.ideal(exact) - ideal_px)) < 1e-9


@pytest.mark.parametrize("axis", ["x", "y"])
def test_camera_points_equal_world_points_in_the_camera_frame(axis):
    # A camera that is not at the world origin: X_cam = (R X + T) * scale, float32, NaN where invalid.
    base = synthetic_rig(camera_size=(160, 120), baseline=axis)
    rig = moved_world(base, rotation("x", 20.0) @ rotation("y", -35.0), np.array([40.0, -300.0, 900.0]))
    tri = Triangulator(rig, axis=axis)
    coord, _ = wavy_coordinates(Triangulator(base, axis=axis), 0 if axis == "x" else 1)
    coord[5, 7] = np.nan
    expected = (tri.points(coord) @ rig.camera.R.T + rig.camera.T) * 1e-3
    ours = tri.camera_points(coord, scale=1e-3)
    assert ours.dtype == np.float32 and ours.shape == (120, 160, 3)
    assert np.isnan(ours[5, 7]).all() and np.isfinite(np.delete(ours.reshape(-1, 3), 5 * 160 + 7, 0)).all()
    finite = np.isfinite(expected[..., 2])
    np.testing.assert_allclose(ours[finite], expected[finite], rtol=2e-7, atol=1e-9)  # float32 rounding
    np.testing.assert_allclose(tri.camera_points(coord, dtype=np.float64)[finite], expected[finite] * 1e3,
                               rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(tri.depth(tri.points(coord))[finite], expected[finite][:, 2] * 1e3, rtol=1e-12)


def test_camera_points_are_nan_behind_the_camera():
    rig = synthetic_rig(camera_size=(64, 48), distortion=False)
    tri = Triangulator(rig, distortion=False)
    t = tri.ray_parameter(np.full(tri.shape, 800.0))
    assert np.all(t < 0)  # this projector column's plane crosses the rays behind the camera
    assert np.isnan(tri.camera_points(np.full(tri.shape, 800.0))).all()
    assert np.isfinite(tri.points(np.full(tri.shape, 800.0))).all()  # points() keeps them


def test_zero_projector_distortion_and_zero_iterations_skip_the_polynomial():
    rig = with_projector_dist(synthetic_rig(camera_size=(64, 48)), np.zeros(5))
    tri = Triangulator(rig)
    coord, truth = wavy_coordinates(tri)
    assert tri._projector_distortion is None
    assert np.max(np.abs(tri.points(coord) - truth)) < 1e-8
    # projector_iterations=0: the measured coordinate is taken as ideal (the projector's distortion ignored).
    distorted = synthetic_rig(camera_size=(64, 48))
    coord = np.full((48, 64), 450.0)
    plain = Triangulator(distorted, projector_iterations=0)
    assert plain._projector_distortion is None
    np.testing.assert_allclose(plain.points(coord), plain._points_on_plane(coord))
