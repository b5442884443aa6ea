"""Registration: the reference object's pose fitted to the measured projector coordinate.

The measured absolute phase gives each pixel's projector coordinate ``x_p = phi W / (2 pi f)`` (the
convention of docs/architecture.md). The pose (sphere centre with the certified diameter; plane tilts and depth) is
the one whose exact ray-surface hits (:func:`dptpu.sim.diagnosis.reference.surface_hits`) project to the measured
coordinates in least squares; optional extra parameters change the rig (e.g. the lens distortion the calibration
lacks) and are fitted jointly. The start is a geometric fit of the triangulated points.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from dptpu.fpp.calibration import Rig
from dptpu.fpp.fitting import fit_plane, fit_sphere
from dptpu.fpp.triangulate import Triangulator, camera_rays

from .reference import Reference, surface_hits

__all__ = ["Registration", "register", "register_robust", "initial_pose"]

#: Registration drops pixels whose residual exceeds this many robust sigmas (or MIN_OUTLIER_PX) and refits:
#: wrong fringe orders are whole periods off and would pull a least-squares pose.
OUTLIER_SIGMAS = 8.0
MIN_OUTLIER_PX = 0.5


@dataclass(frozen=True)
class Registration:
    """A fitted pose: ``pose`` (3,), ``extra`` (k,) rig parameters, ``rig`` (the rig they give), ``model_x``
    (H, W) projector coordinate of the fitted surface (NaN off it), ``residual_px`` (H, W) model - measured on
    the fitted pixels (NaN elsewhere), ``rms_px`` over them."""

    pose: np.ndarray
    extra: np.ndarray
    rig: Rig
    model_x: np.ndarray
    residual_px: np.ndarray
    rms_px: float
    pixels: int
    mask: np.ndarray
    diameter: float | None = None
    offset_px: float = 0.0
    order_errors: float = 0.0
    pose_change: dict | None = None


def initial_pose(rig: Rig, reference: Reference, measured_x: np.ndarray, mask: np.ndarray, axis: str = "x"):
    """Pose (3,) from a geometric fit of the triangulated measured points."""
    points = Triangulator(rig, axis=axis).points(np.where(mask, measured_x, 0.0))[mask]
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) < 10:
        raise ValueError(f"registration needs at least 10 valid measured pixels; got {len(points)}")
    if reference.kind == "sphere":
        return fit_sphere(points, radius=reference.sphere_diameter / 2.0).center
    plane = fit_plane(points)
    n_cam = rig.camera.R @ plane.normal
    n_cam = n_cam / -n_cam[2]  # (a, b, -1)
    origin = rig.camera.center
    axis_w = rig.camera.R.T[:, 2]
    depth = (plane.offset - plane.normal @ origin) / (plane.normal @ axis_w)
    return np.array([n_cam[0], n_cam[1], depth])


def register(rig: Rig, reference: Reference, measured_x: np.ndarray, mask: np.ndarray, *,
             rig_of: Callable[[Rig, np.ndarray], Rig] | None = None, extra0=(), pose0=None,
             axis: str = "x", free_diameter: bool = False, free_offset: bool = False,
             wrap_period_px: float | None = None) -> Registration:
    """Fit the pose (and ``extra`` rig parameters through ``rig_of(rig, extra)``) to ``measured_x`` (H, W).

    Parameters
    ----------
    rig : Rig
        The baseline rig.
    reference : Reference
        ``sphere`` or ``plane``.
    measured_x : ndarray (H, W)
        Measured projector coordinate along ``axis``, projector px; NaN where invalid.
    mask : ndarray (H, W) bool
        Pixels to fit.
    rig_of : callable, optional
        ``rig_of(rig, extra) -> Rig``: the rig with extra parameters applied.
    extra0 : sequence of float
        Start of the extra parameters.
    free_diameter : bool
        Fit the sphere's diameter too (an apparent surface below the true one: volume scattering, a scale
        error of the calibration).
    free_offset : bool
        Fit a constant projector-coordinate offset too (a pixel-centre convention, a phase offset).
    wrap_period_px : float, optional
        Compare modulo this period (projector px): ``measured_x`` is then the wrapped coordinate of the high
        frequency, immune to fringe-order errors (:func:`register_robust`).
    """
    if reference.kind not in ("sphere", "plane"):
        raise ValueError(f"registration fits a sphere or a plane; got reference {reference.label!r}")
    index = 0 if axis == "x" else 1
    mask = mask & np.isfinite(measured_x)
    extra0 = np.asarray(extra0, dtype=np.float64)
    pose0 = initial_pose(rig, reference, measured_x, mask, axis) if pose0 is None else np.asarray(pose0, float)
    target = measured_x[mask]
    base_rays = camera_rays(rig.camera)[mask]

    k = len(extra0)

    def unpack(p):
        current = rig if rig_of is None or not k else rig_of(rig, p[3:3 + k])
        tail = list(p[3 + k:])
        diameter = tail.pop(0) if free_diameter else reference.diameter
        offset = tail.pop(0) if free_offset else 0.0
        return current, diameter, offset

    def model(p, extend=True, rays=None):
        current, diameter, offset = unpack(p)
        if rays is None:
            rays = base_rays if current.camera is rig.camera else camera_rays(current.camera)[mask]
        hits = surface_hits(current, reference.kind, p[:3], diameter=diameter, rays=rays, extend=extend)
        return hits.projector_xy[..., index] + offset

    def residuals(p):
        r = model(p) - target
        if wrap_period_px:
            r = np.mod(r + 0.5 * wrap_period_px, wrap_period_px) - 0.5 * wrap_period_px
        return np.where(np.isfinite(r), r, 10.0)

    scale = np.concatenate([[1.0, 1.0, 1.0] if reference.kind == "sphere" else [1e-3, 1e-3, 1.0],
                            np.full(k, 1e-2), [1.0] * free_diameter, [1.0] * free_offset])
    p = np.concatenate([pose0, extra0, [reference.diameter or 0.0] * free_diameter, [0.0] * free_offset])
    for _ in range(2):  # fit, then drop gross outliers (wrong fringe orders: whole periods) and fit again
        p = least_squares(residuals, p, x_scale=scale, method="lm").x
        r = np.abs(residuals(p))
        keep = r <= max(OUTLIER_SIGMAS * 1.4826 * np.median(r), MIN_OUTLIER_PX)
        if keep.all() or keep.sum() < 10:
            break
        mask = mask.copy()
        mask[mask] = keep
        target, base_rays = target[keep], base_rays[keep]
    fitted, diameter, offset = unpack(p)
    hits = surface_hits(fitted, reference.kind, p[:3], diameter=diameter)
    model_x = np.where(hits.lit, hits.projector_xy[..., index] + offset, np.nan)
    residual = np.full(measured_x.shape, np.nan)
    residual[mask] = residuals(p)
    rms = float(np.sqrt(np.nanmean(residual[mask] ** 2)))
    return Registration(pose=p[:3], extra=p[3:3 + k], rig=fitted, model_x=model_x, residual_px=residual,
                        rms_px=rms, pixels=int(mask.sum()), mask=mask, diameter=diameter, offset_px=float(offset))



def register_robust(rig: Rig, reference: Reference, measured_x: np.ndarray, mask: np.ndarray, *,
                    period_px: float, axis: str = "x") -> Registration:
    """:func:`register` on the absolute coordinate, then again on the wrapped one (modulo ``period_px``) from
    that pose.

    An effect that biases the low-frequency phase (a step-scale error, a drift) breaks the temporal unwrapping:
    whole regions get wrong fringe orders, and no pose explains the absolute coordinate. The wrapped
    high-frequency coordinate is immune to that; the pose it gives may be off by whole periods where the
    orders were wrong everywhere (a pose ambiguity the photometric fits absorb with a per-sequence phase
    offset). ``order_errors`` of the result is the fraction of fitted pixels whose decoded order differs from
    the registered twin's.
    """
    first = register(rig, reference, measured_x, mask, axis=axis)
    wrapped = np.mod(measured_x, period_px)
    second = register(rig, reference, wrapped, mask, axis=axis, wrap_period_px=period_px, pose0=first.pose)
    if first.rms_px <= second.rms_px + 1e-6:
        return first
    order_errors = np.abs(measured_x - second.model_x) > 0.5 * period_px
    fitted = second.mask & np.isfinite(second.model_x)
    object.__setattr__(second, "order_errors", float(np.mean(order_errors[fitted])) if fitted.any() else 0.0)
    return second
