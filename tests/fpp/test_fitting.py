import numpy as np
import pytest

from dptpu.fpp.fitting import fit_plane, fit_sphere, fit_sphere_algebraic, rms


def cap_points(n, center, radius, rng, max_polar_deg=70.0):
    """Points on the visible cap of a sphere (as a scanner sees it), (n, 3)."""
    polar = np.radians(rng.uniform(0, max_polar_deg, n))
    azimuth = rng.uniform(0, 2 * np.pi, n)
    directions = np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), -np.cos(polar)], 1)
    return center + radius * directions


def test_algebraic_and_geometric_fits_are_exact_on_noiseless_points():
    rng = np.random.default_rng(0)
    center = np.array([43.1, -57.6, -33.9])
    points = cap_points(2000, center, 25.4041, rng)
    for fit in (fit_sphere_algebraic(points), fit_sphere(points)):
        assert np.max(np.abs(fit.center - center)) < 1e-9
        assert abs(fit.radius - 25.4041) < 1e-9
        assert fit.rms < 1e-9


def test_geometric_fit_rms_matches_the_noise_level():
    rng = np.random.default_rng(0)
    center = np.array([0.0, 0.0, 800.0])
    points = cap_points(20000, center, 25.4041, rng)
    normals = (points - center) / 25.4041
    noisy = points + normals * rng.normal(0, 0.040, (len(points), 1))  # 40 um along the normal
    fit = fit_sphere(noisy)
    assert abs(fit.rms - 0.040) < 0.0015
    assert abs(fit.radius - 25.4041) < 0.003


def test_fixed_radius_fit_recovers_the_center():
    rng = np.random.default_rng(1)
    center = np.array([5.0, -3.0, 790.0])
    points = cap_points(500, center, 25.4041, rng) + rng.normal(0, 0.01, (500, 3))
    fit = fit_sphere(points, radius=25.4041)
    assert fit.radius == 25.4041
    assert np.linalg.norm(fit.center - center) < 0.01


def test_robust_fit_resists_outliers_that_move_least_squares():
    rng = np.random.default_rng(2)
    center = np.array([0.0, 0.0, 800.0])
    points = cap_points(3000, center, 25.0, rng) + rng.normal(0, 0.02, (3000, 3))
    points[:150] += np.array([0.0, 0.0, -3.0])  # 5 % of points 3 mm off (mixed pixels, reflections)
    plain = fit_sphere(points)
    robust = fit_sphere(points, loss="soft_l1", f_scale=0.05)
    assert abs(robust.radius - 25.0) < 0.01 < abs(plain.radius - 25.0)


def test_plane_fit_recovers_normal_and_offset():
    rng = np.random.default_rng(3)
    normal = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0])
    xy = rng.uniform(-50, 50, (1000, 2))
    z = (600.0 - normal[0] * xy[:, 0] - normal[1] * xy[:, 1]) / normal[2]
    points = np.column_stack([xy, z]) + normal * rng.normal(0, 0.01, (1000, 1))
    fit = fit_plane(points)
    assert np.allclose(fit.normal, normal, atol=1e-4)
    assert abs(fit.offset - 600.0) < 0.002
    assert abs(fit.rms - 0.01) < 0.001


def test_bad_points_are_refused_with_the_problem_named():
    with pytest.raises(ValueError, match=r"shape \(M, 3\); got \(10, 2\)"):
        fit_sphere(np.zeros((10, 2)))
    with pytest.raises(ValueError, match="NaN"):
        fit_sphere(np.full((10, 3), np.nan))
    with pytest.raises(ValueError, match="at least 4 points"):
        fit_sphere_algebraic(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="empty"):
        rms(np.array([]))
