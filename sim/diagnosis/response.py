"""The ``projector_response`` candidate: a monotone lookup-table response of the projector, fitted by
constrained least squares beside the power law (``projector_gamma``); BIC decides between them.

The table holds ``K`` knots ``l_k`` at inputs ``k / (K - 1)`` and is linear between them (the effect's
definition, :func:`dptpu.sim.effects.pattern.response_levels`), so a model value is linear in the knots:
``M_v = FS R_q s_q sum_k w_k(p_v) l_k`` with ``w_k`` the hat functions at the ideal level ``p_v`` of the value
(Eq. (1) at the pixel's projector coordinate). Monotone: ``l = C d`` with ``C`` the cumulative sum and the
increments ``d >= 0`` (non-negative least squares, :func:`scipy.optimize.nnls`). The per-pixel gain
``s_q`` and the table are fitted in turn (a few alternations from the ideal table); the scale they share is
fixed by ``L(p_max) = p_max`` at the brightest projected level. Only the knots whose hat functions reach the
projected range ``[offset - amplitude, offset + amplitude]`` are free (the others repeat the nearest free one);
their number less one (the scale) is the candidate's parameter count in the BIC.

Scoring is that of every candidate: the intensity residual with the table as an effect (gain and phase
offsets fitted, :func:`dptpu.sim.diagnosis.forward.intensity_residual`).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from dptpu.sim.effects.pattern import pattern_levels

from .forward import PixelSet, fit_gain, intensity_residual
from .selection import delta_bic, gain

__all__ = ["RESPONSE_KNOTS", "fit_response", "active_knots"]

#: Knots of the fitted table (spacing 1/11 of full scale).
RESPONSE_KNOTS = 12
#: Alternations of table and gain.
ALTERNATIONS = 4


def active_knots(low: float, high: float, knots: int) -> np.ndarray:
    """Indices of the knots whose hat functions (width ``2 / (K - 1)``) reach ``[low, high]``."""
    x = np.linspace(0.0, 1.0, knots)
    h = 1.0 / (knots - 1)
    return np.nonzero((x + h > low) & (x - h < high))[0]


def _hat_weights(levels: np.ndarray, knots: int) -> np.ndarray:
    """(V, K) weights of the piecewise-linear interpolation at ``levels`` (V,)."""
    position = np.clip(levels, 0.0, 1.0) * (knots - 1)
    left = np.minimum(np.floor(position).astype(int), knots - 2)
    t = position - left
    weights = np.zeros((levels.size, knots))
    rows = np.arange(levels.size)
    weights[rows, left] = 1.0 - t
    weights[rows, left + 1] = t
    return weights


def _nonnegative_lsq(design: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``argmin |A d - b|`` over ``d >= 0``, on the normal equations (``A^T A = L L^T``: the same problem as
    ``|L^T d - L^-1 A^T b|``, K x K instead of V x K)."""
    normal = design.T @ design
    normal += 1e-12 * np.trace(normal) * np.eye(len(normal))
    lower = np.linalg.cholesky(normal)
    rhs = np.linalg.solve(lower, design.T @ target)
    return nnls(lower.T, rhs)[0]


def _ideal_levels(pixels: PixelSet) -> list:
    """Ideal projected level (N, P) of every value (Eq. (1))."""
    out = []
    for sequence, coord in zip(pixels.sequences, pixels.coords):
        n = np.arange(sequence.steps)
        shifts = sequence.shift_sign * 2.0 * np.pi * n / sequence.steps
        out.append(np.stack([pattern_levels(coord, frequency=sequence.frequency, extent=pixels.extent, shift=s,
                                            offset=pixels.offset, amplitude=pixels.amplitude,
                                            phase_offset=sequence.phase_offset) for s in shifts]))
    return out


def fit_response(pixels: PixelSet, *, base=(), refine: int = 1, rss_before: float | None = None,
                 knots: int = RESPONSE_KNOTS) -> dict:
    """Fit the monotone table on top of ``base`` effects (camera-stage ones: they act after it); returns an
    effect entry (report.json) whose ``parameters`` are the effect's ``levels``."""
    n = pixels.values
    base = list(base)
    if rss_before is None:
        residual, _, _ = intensity_residual(pixels, base, refine=refine)
        rss_before = float(sum(np.sum(r * r) for r in residual))
    levels = _ideal_levels(pixels)
    p = np.concatenate([lv.ravel() for lv in levels])
    measured = np.concatenate([m.ravel() for m in pixels.measured])
    steps = [lv.shape[0] for lv in levels]
    low, high = pixels.offset - pixels.amplitude, pixels.offset + pixels.amplitude
    active = active_knots(low, high, knots)
    weights = _hat_weights(p, knots)
    # fold the inactive knots into their nearest active one (they repeat its value)
    folded = np.zeros((weights.shape[0], active.size))
    nearest = np.clip(np.searchsorted(active, np.arange(knots)), 0, active.size - 1)
    for k in range(knots):
        folded[:, nearest[k]] += weights[:, k]
    cumulative = np.tril(np.ones((active.size, active.size)))
    table = np.linspace(0.0, 1.0, knots)[active]
    gains = fit_gain(pixels.measured, [pixels.full_scale * pixels.factor * lv for lv in levels])
    for _ in range(ALTERNATIONS):
        scale = np.concatenate([np.repeat((pixels.full_scale * pixels.factor * gains)[None, :], s, axis=0).ravel()
                                for s in steps])
        design = (folded * scale[:, None]) @ cumulative
        increments = _nonnegative_lsq(design, measured)
        table = cumulative @ increments
        model, start = [], 0
        for lv in levels:
            size = lv.size
            model.append((folded[start:start + size] @ table).reshape(lv.shape) * pixels.full_scale * pixels.factor)
            start += size
        gains = fit_gain(pixels.measured, model)
    inputs = np.linspace(0.0, 1.0, knots)
    full = table[nearest]
    top = float(np.interp(high, inputs, full))
    if top > 0:
        full = full * high / top
    full = np.maximum.accumulate(np.clip(full, 0.0, None))
    entry_levels = [float(f"{v:.6g}") for v in full]
    effect = {"projector_response": {"levels": entry_levels}}
    residual, _, _ = intensity_residual(pixels, base + [effect], refine=refine)
    rss = float(sum(np.sum(r * r) for r in residual))
    k = int(active.size) - 1
    before, after = float(np.sqrt(rss_before / n)), float(np.sqrt(rss / n))
    return {"name": "projector_response", "parameters": {"levels": entry_levels}, "residual_before": before,
            "residual_after": after, "gain": gain(before, after),
            "evidence": {"domain": "intensity", "unit": "DN", "values": n, "parameters": k,
                         "delta_bic": delta_bic(rss_before, rss, n, k), "knots": knots,
                         "free_knots": [int(a) for a in active]}}
