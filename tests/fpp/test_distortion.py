import numpy as np

from dptpu.fpp.distortion import distort, distort_pixels, undistort, undistort_pixels

REAL_CAMERA_DIST = np.array([-0.1289, -0.5635, -0.00138, -0.00038, 0.0])  # the DP-TPU rig's camera
K = np.array([[2592.2, -0.233, 309.0], [0, 2592.7, 236.2], [0, 0, 1]])


def test_undistort_inverts_distort_over_the_field_of_view():
    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.15, 0.15, size=(5000, 2))  # beyond the 640x480 field of view of the 12 mm lens
    assert np.max(np.abs(undistort(distort(xy, REAL_CAMERA_DIST), REAL_CAMERA_DIST) - xy)) < 1e-12


def test_pixel_round_trip_with_skew():
    v, u = np.mgrid[0:480:7, 0:640:7].astype(float)
    uv = np.stack([u, v], axis=-1)
    assert np.max(np.abs(distort_pixels(undistort_pixels(uv, K, REAL_CAMERA_DIST), K, REAL_CAMERA_DIST) - uv)) < 1e-9


def test_radial_distortion_matches_the_polynomial_on_the_axis():
    # On the x axis with only k1, k2: x_d = x (1 + k1 x^2 + k2 x^4).
    x = 0.1
    expected = x * (1 - 0.1289 * x**2 - 0.5635 * x**4)
    dist = np.array([-0.1289, -0.5635, 0.0, 0.0, 0.0])
    assert abs(distort(np.array([[x, 0.0]]), dist)[0, 0] - expected) < 1e-15
