"""The ``motion`` candidate: the reference moved between frames, fitted with the twin in the loop.

With raw frames and a registered reference, frame ``g`` of the capture (0-based over the sequences in order)
sees each pixel's projector coordinate moved by ``(g - g_ref) J v`` (:mod:`.forward`: ``J`` the derivative of
the coordinate with respect to a translation of the surface, ``g_ref`` the frame of the registered pose). The
velocity ``v`` (rig units per frame) is fitted by least squares on the intensity residual (Levenberg-Marquardt
from rest, the per-pixel gain and the per-sequence phase offsets fitted in closed form at each evaluation), in
the translations the reference can show (:func:`identifiable_directions`). Rotation is not fitted: a sphere
turning about its centre is invisible, and for the other references it is left out (docs/sim-to-real.md).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from .forward import PixelSet, intensity_residual
from .reference import plane_normal
from .selection import delta_bic, gain

__all__ = ["identifiable_directions", "fit_motion"]


def identifiable_directions(rig, reference, pose) -> np.ndarray:
    """World directions (3, k) of the translations the reference shows: a sphere or a scene all three; a plane
    only along its normal (sliding in its own plane changes nothing)."""
    if reference.kind == "plane":
        return plane_normal(rig, np.asarray(pose)[:2])[:, None]
    return np.eye(3)


def _effect(velocity) -> dict:
    return {"motion": {"velocity_per_frame": [float(v) for v in velocity], "angular_deg_per_frame": [0.0] * 3}}


def fit_motion(pixels: PixelSet, directions: np.ndarray, *, base=(), refine: int = 1,
               rss_before: float | None = None, speed_scale: float | None = None) -> dict:
    """Fit the velocity along ``directions`` (3, k) on top of ``base`` effects; returns an effect entry.

    ``speed_scale`` (rig units per frame) is the typical size of a component, for the solver's scaling
    (default: the motion that moves the mean pixel by 0.1 projector px per frame)."""
    n = pixels.values
    base = list(base)
    if rss_before is None:
        residual, _, _ = intensity_residual(pixels, base, refine=refine)
        rss_before = float(sum(np.sum(r * r) for r in residual))
    k = directions.shape[1]
    if speed_scale is None:
        per_unit = np.abs(pixels.motion_jacobian @ directions).mean()
        speed_scale = 0.1 / max(float(per_unit), 1e-12)

    def residuals(coefficients):
        velocity = directions @ (np.asarray(coefficients) * speed_scale)
        residual, _, _ = intensity_residual(pixels, base + [_effect(velocity)], refine=refine)
        return np.concatenate([r.ravel() for r in residual])

    solution = least_squares(residuals, np.zeros(k), method="lm", x_scale=np.ones(k), diff_step=1e-3)
    velocity = directions @ (solution.x * speed_scale)
    rss = float(np.sum(solution.fun ** 2))
    if rss > rss_before:  # never worse than at rest
        velocity, rss = np.zeros(3), rss_before
    before, after = float(np.sqrt(rss_before / n)), float(np.sqrt(rss / n))
    return {"name": "motion", "parameters": _effect(velocity)["motion"], "residual_before": before,
            "residual_after": after, "gain": gain(before, after),
            "evidence": {"domain": "intensity", "unit": "DN", "values": n, "parameters": k,
                         "delta_bic": delta_bic(rss_before, rss, n, k), "directions": directions.T.tolist()}}
