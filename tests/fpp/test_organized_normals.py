"""Normals of organized clouds (fpp.organized_normals) against analytic planes and spheres."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.organized_normals import organized_normals
from dptpu.fpp.texture import texture_image

FOCAL_PX = 400.0
SHAPE = (120, 160)


def rays() -> np.ndarray:
    """(H, W, 3) pinhole rays z = 1 of a 160 x 120 camera, principal point at the centre."""
    v, u = np.mgrid[0:SHAPE[0], 0:SHAPE[1]].astype(float)
    return np.stack([(u - 79.5) / FOCAL_PX, (v - 59.5) / FOCAL_PX, np.ones(SHAPE)], axis=-1)


def plane_points(normal, point) -> np.ndarray:
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    r = rays()
    return r * ((normal @ np.asarray(point, float)) / (r @ normal))[..., None]


def sphere_points(centre, radius) -> tuple[np.ndarray, np.ndarray]:
    """Points (NaN off the sphere) and their outward unit normals."""
    r = rays()
    r /= np.linalg.norm(r, axis=-1, keepdims=True)
    b = r @ np.asarray(centre, float)
    disc = b * b - (np.dot(centre, centre) - radius**2)
    with np.errstate(invalid="ignore"):
        points = r * (b - np.sqrt(disc))[..., None]
    return points, (points - np.asarray(centre, float)) / radius


def angle_deg(a, b) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


@pytest.mark.parametrize("normal", [(0.12, -0.08, -1.0), (0.5, 0.3, -1.0), (-0.7, 0.0, -0.5)])
def test_a_plane_gets_its_analytic_normal_toward_the_camera_at_every_pixel(normal):
    points = plane_points(normal, (0.0, 0.0, 0.85))  # metres; the normal faces the camera (its z < 0)
    truth = np.asarray(normal) / np.linalg.norm(normal)
    for window in (1, 3, 5):
        normals = organized_normals(points, window_px=window)
        assert normals.dtype == np.float32 and normals.shape == (*SHAPE, 3)
        finite = np.isfinite(normals[..., 0])
        # the image's border has no central difference of its own; a window takes its neighbours'
        assert finite.all() if window > 1 else (finite[1:-1, 1:-1].all() and finite.sum() == 118 * 158)
        assert angle_deg(normals[finite].astype(float), truth).max() < 0.05  # float32 differences: measured 0.03 deg
        flipped = organized_normals(points[:, ::-1], window_px=window)  # mirrored grid: still toward the camera
        assert np.all(np.sum(flipped * points[:, ::-1], axis=-1)[finite] < 0)


def test_a_sphere_within_one_degree_with_the_noise_of_a_scan():
    """A 60 mm sphere at 800 mm (about 30 px radius), depth noise 0.05 mm (the twin's sphere at 64x12 steps:
    depth RMS 0.04 mm, docs/scanner.md): 3 x 3 windows keep the normals within 1 deg (measured median 0.34 deg,
    90th percentile 0.58 deg; the point's own central differences: 0.83 / 1.74 deg)."""
    points, truth = sphere_points(np.array([10.0, -5.0, 800.0]), 60.0)  # mm
    exact = organized_normals(points, window_px=1).astype(float)
    # central differences of exact points where the sphere faces the camera within 60 deg: measured median 0.036,
    # max 0.22 deg (the curvature between the samples, 2 mm apart on a 60 mm radius)
    facing = -np.sum(truth * points, axis=-1) / np.linalg.norm(points, axis=-1) > 0.5
    exact_errors = angle_deg(exact, truth)[facing & np.isfinite(exact[..., 0])]
    assert np.median(exact_errors) < 0.05 and exact_errors.max() < 0.3
    rng = np.random.default_rng(0)
    noisy = points * (1.0 + rng.normal(0.0, 0.05, SHAPE) / points[..., 2])[..., None]  # 0.05 mm along each ray
    errors = angle_deg(organized_normals(noisy, window_px=3).astype(float), truth)[facing]
    assert np.median(errors) < 0.5 and np.percentile(errors, 90) < 1.0


def test_missing_points_have_no_normal_and_their_neighbours_take_the_tangents_their_window_has():
    points = plane_points((0.12, -0.08, -1.0), (0.0, 0.0, 0.85))
    points[40, 50] = np.nan  # a hole: its neighbours' own central differences are NaN, their windows' are not
    points[80:, 100:] = np.nan
    points[10, 10:13] = np.nan
    points[9, 10:13] = points[11, 10:13] = np.nan
    points[10, 9] = points[10, 13] = np.nan
    points[10, 11] = (0.1, 0.1, 0.9)  # an isolated point: no finite tangent in its window
    truth = np.array([0.12, -0.08, -1.0]) / np.linalg.norm([0.12, -0.08, -1.0])
    normals = organized_normals(points, window_px=3)
    assert np.isnan(normals[40, 50]).all() and np.isnan(normals[80:, 100:]).all()
    assert np.isnan(normals[10, 11]).all()
    assert angle_deg(normals[39:42, 49:52].astype(float), truth)[np.isfinite(normals[39:42, 49:52, 0])].max() < 0.05
    assert np.isfinite(normals[39:42, 49:52, 0]).sum() == 8  # every neighbour of the hole
    assert angle_deg(normals[79, 100:].astype(float), truth).max() < 0.05  # the edge of a missing block
    own = organized_normals(points, window_px=1)  # the point's own central differences only
    assert np.isnan(own[40, 49]).all() and np.isnan(own[79, 100:]).all()


def test_bad_input_is_refused_with_the_expected_form():
    with pytest.raises(ValueError, match=r"points must have shape \(H, W, 3\); got \(4, 4\)"):
        organized_normals(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="window_px must be an odd integer >= 1; got 2"):
        organized_normals(np.zeros((4, 4, 3)), window_px=2)


def test_texture_is_white_minus_black_or_the_mean_intensity():
    white = np.full((2, 3), 200, np.uint8)
    black = np.full((2, 3), 12, np.uint8)
    assert np.array_equal(texture_image(white=white, black=black), np.full((2, 3), 188, np.float32))
    assert np.array_equal(texture_image(white=white), np.full((2, 3), 200, np.float32))
    background = np.full((2, 3), 99.5, np.float32)
    assert np.array_equal(texture_image(background=background, white=white), np.full((2, 3), 200, np.float32))
    assert np.array_equal(texture_image(background=background), background)
    with pytest.raises(ValueError, match="a black frame needs a white frame"):
        texture_image(background=background, black=black)
    with pytest.raises(ValueError, match="black must have the white frame's shape"):
        texture_image(white=white, black=black[:1])


def reference_normals(points: np.ndarray, window: int) -> np.ndarray:
    """The module docstring's definition written plainly (NaN tangents, masked box sums, one float32 operation at a
    time in the kernel's order): the kernel before it was made lean (issue 20), kept to hold it to the same bits."""
    import cv2

    p = [points[..., c].astype(np.float32) for c in range(3)]
    sums = []
    for axis in (1, 0):
        t = [np.full_like(plane, np.nan) for plane in p]
        for plane, d in zip(p, t):
            if axis == 0:
                d[1:-1] = plane[2:] - plane[:-2]
            else:
                d[:, 1:-1] = plane[:, 2:] - plane[:, :-2]
        finite = ~np.isnan(t[2])
        count = cv2.boxFilter(finite.astype(np.float32), -1, (window, window), normalize=False,
                              borderType=cv2.BORDER_CONSTANT)
        summed = [cv2.boxFilter(np.where(finite, d, np.float32(0.0)), -1, (window, window), normalize=False,
                                borderType=cv2.BORDER_CONSTANT) for d in t]
        for s in summed:
            s[count < 0.5] = np.nan
        sums.append(summed)
    tu, tv = sums
    n = [tu[a] * tv[b] - tu[b] * tv[a] for a, b in ((1, 2), (2, 0), (0, 1))]
    length = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    facing = n[0] * p[0] + n[1] * p[1] + n[2] * p[2]
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(facing > 0, np.float32(-1.0), np.float32(1.0)) / length
    scale[np.isnan(facing) | ~np.isfinite(scale)] = np.nan
    return np.stack([c * scale for c in n], axis=-1)


@pytest.mark.parametrize("window", [1, 3, 5, 7])
def test_the_kernel_gives_the_plain_definitions_bits(window):
    """Bit for bit the plain definition (:func:`reference_normals`) on a noisy sphere before a tilted plane with
    holes, single pixels and rows missing, in float64 and float32, interleaved or as a planar view, with ``out``."""
    sphere, _ = sphere_points(np.array([10.0, -5.0, 800.0]), 60.0)
    points = plane_points((0.3, -0.2, -1.0), (0.0, 0.0, 900.0))
    on_sphere = np.isfinite(sphere[..., 2])
    points[on_sphere] = sphere[on_sphere]
    rng = np.random.default_rng(7)
    points *= (1.0 + rng.normal(0.0, 0.05, SHAPE) / points[..., 2])[..., None]
    points[rng.random(SHAPE) < 0.03] = np.nan  # lone missing pixels
    points[30:34] = np.nan
    points[:, 150:] = np.nan
    points[70, 20] = (5.0, 5.0, 850.0)  # an isolated point
    points[69, 19:22] = points[71, 19:22] = points[70, 19] = points[70, 21] = np.nan
    expected = reference_normals(points, window)
    assert 0.5 < np.isfinite(expected[..., 0]).mean() < 0.95  # the case has normals and holes
    planar = np.ascontiguousarray(points.transpose(2, 0, 1), dtype=np.float32)  # (3, H, W) as the cloud node has
    out = np.empty((3, *SHAPE), dtype=np.float32)
    for given, target in ((points, None), (points.astype(np.float32), None), (planar.transpose(1, 2, 0), None),
                          (planar.transpose(1, 2, 0), out.transpose(1, 2, 0))):
        normals = organized_normals(given, window_px=window, out=target)
        np.testing.assert_array_equal(normals, expected)
    assert np.shares_memory(normals, out)
