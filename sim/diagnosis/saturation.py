"""The ``saturation`` candidate: the camera clips at one level in DN, whatever the pixel's brightness.

The camera's full well (or its ADC) clips the *recorded* value: a pixel of albedo ``rho`` and shading ``cos``
clips where ``exposure_gain * FS * R_q * p_n >= level * FS``, i.e. at a projected level that depends on the
pixel's reflectance factor ``R_q``. The projector's response (``projector_gamma``, ``projector_response``)
bends the *projected* level ``p`` before any pixel sees it: the same ``p`` on every pixel, scaled by the pixel's
gain afterwards. The two are told apart by where the per-pixel gain acts:

    saturation:  I_n(q) = min(s_q M_n(q), level FS)          response:  I_n(q) = s_q FS R_q L(p_n(q))

so that a bright pixel clips at the same DN as a dark one, and earlier in the fringe. (The generic fit,
``s_q min(g FS R_q p, FS)``, placed the clip by the twin's reflectance factor: on a surface whose albedo or
shading the twin does not know it clipped at the wrong DN and a lookup table with its free knots fitted the
flattened tops better.)

The fit: for a clip ``level`` (fraction of full scale, bounded search on [0.5, 1]; the ADC clips at 1 anyway),
``s_q`` is fitted on the values the model leaves below the clip (two passes, starting from the measured values
below it), and the residual is ``I - min(s_q M, level FS)``. ``M`` is the twin's frames with the ``base``
effects and their phase offsets (:func:`dptpu.sim.diagnosis.forward.intensity_residual`). The effect's
``exposure_gain`` is the median of ``s_q`` over the pixels: the factor by which the data are brighter than the
twin's reference surface (exact when the reference's material is the twin's; on another material the typical
ratio, which gives the extended twin the same share of clipped values). One parameter in the BIC (the level;
the gains are the nuisance every candidate has).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from .forward import PixelSet, intensity_residual
from .selection import delta_bic, gain

__all__ = ["LEVEL_BOUNDS", "fit_saturation", "clipped_model"]

#: Search range of the clip level, fraction of full scale.
LEVEL_BOUNDS = (0.5, 1.0)
#: A measured value within this many DN of the clip counts as clipped (the 8-bit rounding of a flat top).
CLIP_MARGIN_DN = 1.0


def clipped_model(measured: np.ndarray, shape: np.ndarray, clip_dn: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel gain ``s`` (P,) and model ``min(s M, clip)`` (F, P) for ``measured`` and ``shape`` = ``M`` (F, P).

    ``s`` is fitted on the values below the clip: first the measured ones, then those the model leaves below it;
    a pixel clipped in every frame gets the gain at which its faintest model value reaches the clip."""
    below = measured < clip_dn - CLIP_MARGIN_DN
    s = np.zeros(measured.shape[1])
    for _ in range(2):
        numerator = np.sum(np.where(below, measured * shape, 0.0), axis=0)
        denominator = np.sum(np.where(below, shape * shape, 0.0), axis=0)
        every_frame = clip_dn / np.maximum(shape.min(axis=0), 1e-9)
        s = np.where(denominator > 0, numerator / np.maximum(denominator, 1e-12), every_frame)
        below = s[None, :] * shape < clip_dn
    return s, np.minimum(s[None, :] * shape, clip_dn)


def fit_saturation(pixels: PixelSet, *, base=(), refine: int = 1, rss_before: float) -> dict:
    """Fit the clip level and the exposure gain on top of ``base`` effects; returns an effect entry."""
    n = pixels.values
    _, pixel_gain, model = intensity_residual(pixels, list(base), refine=refine)
    measured = np.concatenate(pixels.measured, axis=0)
    safe = np.where(pixel_gain > 0, pixel_gain, 1.0)
    shape = np.concatenate(model, axis=0) / safe[None, :]  # the twin's frames M, gain divided out

    def rss(level: float) -> float:
        _, fitted = clipped_model(measured, shape, level * pixels.full_scale)
        return float(np.sum((measured - fitted) ** 2))

    lo, hi = LEVEL_BOUNDS
    grid = np.linspace(lo, hi, 6)
    values = [rss(v) for v in grid]
    best = int(np.argmin(values))
    level, best_rss = float(grid[best]), float(values[best])
    left, right = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    solution = minimize_scalar(rss, bounds=(left, right), method="bounded", options={"xatol": 1e-4})
    if solution.fun < best_rss:
        level, best_rss = float(solution.x), float(solution.fun)
    s, fitted = clipped_model(measured, shape, level * pixels.full_scale)
    exposure_gain = float(np.median(s)) if s.size else 1.0
    clipped = fitted >= level * pixels.full_scale
    before, after = float(np.sqrt(rss_before / n)), float(np.sqrt(best_rss / n))
    return {"name": "saturation", "parameters": {"exposure_gain": exposure_gain, "level": level},
            "residual_before": before, "residual_after": after, "gain": gain(before, after),
            "evidence": {"domain": "intensity", "unit": "DN", "values": n, "parameters": 1,
                         "delta_bic": delta_bic(rss_before, best_rss, n, 1),
                         "model": "clip at one DN level after the per-pixel gain",
                         "clipped_fraction": float(np.mean(clipped)),
                         "clip_dn": level * pixels.full_scale}}
