"""Table 1 (Blender parameters from a calibration) and the OpenCV -> Blender camera convention, without Blender."""
import numpy as np
import pytest

from dptpu.fpp.calibration import DeviceModel, load_bouguet_pair
from dptpu.sim.blender_params import (
    blender_rotation,
    camera_parameters,
    euler_xyz_from_matrix,
    matrix_from_euler_xyz,
    project_blender_camera,
    projector_parameters,
    spot_size_rad,
    twin_parameters,
)


def _random_rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _opencv_project(device: DeviceModel, points: np.ndarray) -> np.ndarray:
    local = points @ device.R.T + device.T
    pixels = local @ device.K.T
    return pixels[:, :2] / pixels[:, 2:]


def test_euler_xyz_of_eq14_round_trips_random_rotations():
    rng = np.random.default_rng(0)
    for _ in range(200):
        M = _random_rotation(rng)
        np.testing.assert_allclose(matrix_from_euler_xyz(euler_xyz_from_matrix(M)), M, atol=1e-12)


def test_euler_xyz_of_eq14_recovers_known_angles_in_blender_order():
    # Blender's 'XYZ' mode rotates about x first: M = Rz(phi) Ry(theta) Rx(psi)
    angles = np.radians([30.0, -20.0, 110.0])
    M = matrix_from_euler_xyz(angles)
    a, b, c = angles
    Rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    Rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    np.testing.assert_allclose(M, Rz @ Ry @ Rx, atol=1e-15)
    np.testing.assert_allclose(euler_xyz_from_matrix(M), angles, atol=1e-12)


def test_convention_blender_camera_projects_points_like_opencv():
    """Blender's camera (local -Z forward, +Y up, lens/sensor/shift) and OpenCV's (+Z forward, +Y down, K) agree."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        R = _random_rotation(rng)
        centre = rng.normal(0, 300, 3)
        device = DeviceModel(K=[[900.0, 0.0, 301.7], [0.0, 900.0, 262.2], [0.0, 0.0, 1.0]], dist=np.zeros(5), R=R,
                             T=-R @ centre, size=(640, 480))
        local = np.column_stack([rng.uniform(-300, 300, 50), rng.uniform(-200, 200, 50), rng.uniform(500, 1500, 50)])
        points = (local - device.T) @ device.R  # (50, 3) in front of the camera
        camera = camera_parameters(device)
        np.testing.assert_allclose(camera.location, centre, atol=1e-9)
        np.testing.assert_allclose(project_blender_camera(camera, points), _opencv_project(device, points),
                                   atol=1e-9)


def test_convention_blender_principal_point_to_shift():
    device = DeviceModel(K=[[1000.0, 0, 319.5], [0, 1000.0, 239.5], [0, 0, 1]], dist=np.zeros(5), R=np.eye(3),
                         T=np.zeros(3), size=(640, 480))
    camera = camera_parameters(device)
    assert camera.shift_x == 0.0 and camera.shift_y == 0.0  # the image centre, 0-based
    shifted = camera_parameters(DeviceModel(K=[[1000.0, 0, 319.5 - 64], [0, 1000.0, 239.5 + 32], [0, 0, 1]],
                                            dist=np.zeros(5), R=np.eye(3), T=np.zeros(3), size=(640, 480)))
    assert shifted.shift_x == pytest.approx(0.1)  # principal point left of centre: the window moves right
    assert shifted.shift_y == pytest.approx(0.05)  # both shifts in image widths
    assert camera.rotation_euler == pytest.approx([np.pi, 0.0, 0.0])  # OpenCV's identity looks down Blender's -Z


def test_skew_and_unequal_focal_lengths_are_reported_not_rendered():
    device = DeviceModel(K=[[1732.0, -0.95, 443.1], [0, 3463.3, 588.1], [0, 0, 1]], dist=np.zeros(5),
                         R=np.eye(3), T=np.zeros(3), size=(912, 1140))
    camera = camera_parameters(device, pixel_pitch_mm=0.01)
    assert camera.lens_mm == pytest.approx(17.32)
    assert camera.pixel_aspect == pytest.approx(3463.3 / 1732.0)
    assert camera.skew_factor == pytest.approx(-0.95 / 1732.0)


def test_sensor_narrower_than_blender_allows_is_an_error():
    device = DeviceModel(K=[[650.0, 0, 79.5], [0, 650.0, 59.5], [0, 0, 1]], dist=np.zeros(5), R=np.eye(3),
                         T=np.zeros(3), size=(160, 120))
    with pytest.raises(ValueError, match="sensor width must be >= 1.0 mm"):
        camera_parameters(device)  # 160 px x 4.8 um = 0.77 mm: Blender would clamp it
    assert camera_parameters(device, sensor_width_mm=36.0).lens_mm == pytest.approx(650.0 * 36.0 / 160)


def test_spot_size_holds_every_projector_pixel():
    device = DeviceModel(K=[[1732.0, -0.95, 443.1], [0, 3463.3, 588.1], [0, 0, 1]], dist=[-0.05, 1.5, 0, 0, 0],
                         R=np.eye(3), T=np.zeros(3), size=(912, 1140))
    half = spot_size_rad(device, margin_rad=0.0) / 2
    rows, cols = np.mgrid[-0.5:1140:20.0, -0.5:912:16.0]
    from dptpu.fpp.distortion import pixels_to_normalized, undistort
    xy = undistort(pixels_to_normalized(np.stack([cols, rows], -1), device.K), device.dist)
    angles = np.arctan(np.hypot(xy[..., 0], xy[..., 1]))
    assert angles.max() <= half + 1e-9
    assert angles.max() > half - np.radians(0.5)  # and not much wider


def test_table1_on_the_dptpu_calibration(sphere_dir):
    """The paper's Table 1 (single-argument arctan of R^T entries) gives our Eq. (14) angles on the real rig."""
    rig = load_bouguet_pair(sphere_dir / "CamCalibResult_real.mat", sphere_dir / "PrjCalibResult_real.mat",
                            camera_size=(640, 480), projector_size=(912, 1140))
    for device, parameters in ((rig.camera, camera_parameters(rig.camera)),
                               (rig.projector, projector_parameters(rig.projector))):
        r = device.R.T  # Table 1's r_ij: entries of the camera -> world rotation
        table1 = np.array([np.arctan(r[2, 1] / r[2, 2]), np.arctan(-r[2, 0] / np.hypot(r[2, 1], r[2, 2])),
                           np.arctan(r[1, 0] / r[0, 0])])
        np.testing.assert_allclose(parameters.rotation_euler, table1, atol=1e-12)
        np.testing.assert_allclose(parameters.location, -device.R.T @ device.T, atol=1e-12)  # Eq. (13)
        np.testing.assert_allclose(matrix_from_euler_xyz(parameters.rotation_euler), blender_rotation(device),
                                   atol=1e-12)
    camera = camera_parameters(rig.camera)
    assert camera.location == pytest.approx([109.1986, -93.2745, 835.7891], abs=1e-3)  # mm, board of view 1
    assert camera.lens_mm == pytest.approx(2592.156 * 0.0048, abs=1e-4)  # 12.44 mm: the rig's 12 mm lens
    table = twin_parameters(rig)
    assert table["projector"]["spot_size_deg"] == pytest.approx(34.41, abs=0.01)
    assert table["camera"]["rotation_euler_deg"] == pytest.approx([4.4823, 7.8135, -0.3567], abs=1e-3)
