"""Fitting reference shapes to point clouds: spheres (algebraic, geometric, fixed radius, robust) and planes.

All functions take points as an (M, 3) array in any unit and return results in that unit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares


@dataclass(frozen=True)
class SphereFit:
    """A fitted sphere and its residuals (signed distance to the surface, positive outside), shape (M,)."""

    center: np.ndarray
    radius: float
    residuals: np.ndarray

    @property
    def rms(self) -> float:
        return rms(self.residuals)


@dataclass(frozen=True)
class PlaneFit:
    """A plane ``normal . X = offset`` (unit normal) and signed point distances, shape (M,)."""

    normal: np.ndarray
    offset: float
    residuals: np.ndarray

    @property
    def rms(self) -> float:
        return rms(self.residuals)


def rms(values: np.ndarray) -> float:
    """Root mean square, ``sqrt(mean(v^2))`` (not the standard deviation: a bias counts)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        raise ValueError("RMS of an empty set of residuals")
    return float(np.sqrt(np.mean(values * values)))


def _check_points(points: np.ndarray, minimum: int) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (M, 3); got {points.shape}")
    if len(points) < minimum:
        raise ValueError(f"need at least {minimum} points; got {len(points)}")
    if not np.all(np.isfinite(points)):
        raise ValueError("points contain NaN or inf; select the valid points first")
    return points


def _sphere_residuals(points, center, radius):
    return np.linalg.norm(points - center, axis=1) - radius


def fit_sphere_algebraic(points: np.ndarray) -> SphereFit:
    """Linear least-squares sphere: ``[2x 2y 2z 1] s = x^2 + y^2 + z^2`` (the DP-TPU reconstruction script).

    Minimizes an algebraic distance, which weights points by their distance from the centre; fast and
    closed-form, the starting point of the geometric fit.
    """
    points = _check_points(points, 4)
    A = np.column_stack([2.0 * points, np.ones(len(points))])
    b = np.einsum("ij,ij->i", points, points)
    solution, *_ = np.linalg.lstsq(A, b, rcond=None)
    center = solution[:3]
    radius = float(np.sqrt(solution[3] + center @ center))
    return SphereFit(center, radius, _sphere_residuals(points, center, radius))


def fit_sphere(points: np.ndarray, *, radius: float | None = None, loss: str = "linear",
               f_scale: float = 1.0) -> SphereFit:
    """Geometric sphere fit: minimizes the sum of squared point-to-surface distances.

    Parameters
    ----------
    points : ndarray (M, 3)
    radius : float, optional
        Fix the radius (e.g. a certified sphere) and fit only the centre.
    loss : {"linear", "huber", "soft_l1", "cauchy"}
        "linear" is least squares; the others are robust losses (scipy's ``least_squares``) whose scale is
        ``f_scale`` in the points' unit: residuals much larger than ``f_scale`` lose influence.
    """
    points = _check_points(points, 4 if radius is None else 3)
    if radius is not None and not radius > 0:
        raise ValueError(f"a fixed radius must be positive; got {radius}")
    start = fit_sphere_algebraic(points)
    if radius is None:
        x0 = np.append(start.center, start.radius)

        def residuals(p):
            return _sphere_residuals(points, p[:3], p[3])

        def jacobian(p):
            diff = points - p[:3]
            dist = np.linalg.norm(diff, axis=1, keepdims=True)
            return np.column_stack([-diff / dist, -np.ones(len(points))])
    else:
        x0 = start.center

        def residuals(p):
            return _sphere_residuals(points, p, radius)

        def jacobian(p):
            diff = points - p
            return -diff / np.linalg.norm(diff, axis=1, keepdims=True)

    result = least_squares(residuals, x0, jac=jacobian, loss=loss, f_scale=f_scale, method="trf",
                           x_scale="jac")
    center = result.x[:3]
    fitted_radius = float(result.x[3]) if radius is None else float(radius)
    return SphereFit(center, fitted_radius, _sphere_residuals(points, center, fitted_radius))


def fit_plane(points: np.ndarray) -> PlaneFit:
    """Total least-squares plane through ``points`` (M, 3): the normal is the smallest principal axis."""
    points = _check_points(points, 3)
    centroid = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centroid, full_matrices=False)
    normal = vt[2]
    if normal[2] < 0:
        normal = -normal
    offset = float(normal @ centroid)
    return PlaneFit(normal, offset, points @ normal - offset)
