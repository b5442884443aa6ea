"""Brown-Conrady lens distortion (OpenCV / Bouguet model), forward and inverse, vectorized.

Normalized coordinates are ``(x, y) = (X/Z, Y/Z)`` in the device frame. With ``r^2 = x^2 + y^2``:

    x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y

and pixels are ``K @ [x_d, y_d, 1]`` (skew included). ``dist = (k1, k2, p1, p2, k3)``.
"""
from __future__ import annotations

import numpy as np


def distort(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Apply distortion to normalized coordinates ``xy`` (..., 2); returns distorted (..., 2)."""
    k1, k2, p1, p2, k3 = np.asarray(dist, dtype=np.float64)
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    x_d = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    y_d = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([x_d, y_d], axis=-1)


def undistort(xy_d: np.ndarray, dist: np.ndarray, *, iterations: int = 20) -> np.ndarray:
    """Invert :func:`distort` by fixed-point iteration (as OpenCV's ``undistortPoints``), (..., 2) -> (..., 2).

    Converges for the moderate distortion of metrology lenses; the round trip error is checked in tests.
    """
    k1, k2, p1, p2, k3 = np.asarray(dist, dtype=np.float64)
    x_d, y_d = xy_d[..., 0], xy_d[..., 1]
    x, y = x_d.copy(), y_d.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x = (x_d - dx) / radial
        y = (y_d - dy) / radial
    return np.stack([x, y], axis=-1)


def pixels_to_normalized(uv: np.ndarray, K: np.ndarray) -> np.ndarray:
    """``K^-1`` applied to pixel coordinates (..., 2) -> normalized (still distorted) coordinates (..., 2)."""
    fx, s, cx = K[0]
    fy, cy = K[1, 1], K[1, 2]
    y = (uv[..., 1] - cy) / fy
    x = (uv[..., 0] - cx - s * y) / fx
    return np.stack([x, y], axis=-1)


def normalized_to_pixels(xy: np.ndarray, K: np.ndarray) -> np.ndarray:
    """``K`` applied to normalized coordinates (..., 2) -> pixels (..., 2)."""
    u = K[0, 0] * xy[..., 0] + K[0, 1] * xy[..., 1] + K[0, 2]
    v = K[1, 1] * xy[..., 1] + K[1, 2]
    return np.stack([u, v], axis=-1)


def undistort_pixels(uv: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Distorted pixel coordinates (..., 2) -> ideal (undistorted) pixel coordinates (..., 2), same ``K``."""
    return normalized_to_pixels(undistort(pixels_to_normalized(uv, K), dist), K)


def distort_pixels(uv: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Ideal pixel coordinates (..., 2) -> distorted pixel coordinates (..., 2), same ``K``."""
    return normalized_to_pixels(distort(pixels_to_normalized(uv, K), dist), K)
