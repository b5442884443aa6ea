"""The ``intensity_drift`` candidate with its random part: a per-frame gain (flicker) told apart from sensor noise.

``intensity_drift`` multiplies frame ``n`` of each sequence by ``(1 + rate n)(1 + sigma z_n)``, ``z_n ~ N(0, 1)``
(docs/effects.md). The drift (``rate``) is one parameter and is fitted like every photometric candidate
(:func:`dptpu.sim.diagnosis.candidates.fit_one_parameter`). The flicker (``sigma``) is random, but it is one draw
per *frame*, shared by every pixel of that frame, so a capture shows its realization: the model

    I_n(q) = g_n s_q M_n(q)          (n over all F frames of all sequences, q over the P pixels)

with a gain ``g_n`` per frame and ``s_q`` per pixel (``M`` the twin's frames with the ``base`` effects) is
fitted by alternating least squares (rank one: ``g`` and ``s`` in closed form in turn); the twin's per-sequence
phase offsets are refitted on the frames divided by ``g`` (a few passes: on the low-frequency sequence, whose
phase varies little over the image, a flicker fitted without them biases the offset). Sensor noise is
independent from value to value, so ``F - 1`` frame gains explain only ``(F - 1) / (F P)`` of it: the frame
gains win the BIC against the drift alone only when the frames really share a gain.

The drift law is then fitted to the frame gains: ``g_n = a (1 + rate m_n)`` by least squares (``m_n`` the index
of frame ``n`` within its sequence), and ``sigma`` is the standard deviation of ``g_n / (a (1 + rate m_n)) - 1``
with ``F - 2`` degrees of freedom. The fitted ``sigma`` estimates the parameter from ``F`` draws: its relative
standard error is ``1 / sqrt(2 (F - 2))`` (15 % for the paper's 96x12 + 1x12 capture); the frame gains
themselves (``evidence.frame_gains``) are measured to ~``1e-4`` with a thousand pixels.

The entry is the per-frame model when its ``dBIC`` over the drift alone exceeds
:data:`~dptpu.sim.diagnosis.selection.MIN_DELTA_BIC`; otherwise the drift alone with ``sigma = 0``.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .forward import PixelSet, intensity_residual
from .selection import MIN_DELTA_BIC, delta_bic, gain

__all__ = ["fit_frame_gains", "fit_drift_with_flicker"]

#: Alternations of the frame gains and the pixel gains (rank-one least squares converges in a few).
ALTERNATIONS = 8
#: Passes of (phase offsets of the twin's frames, frame gains): a flicker biases the offsets fitted without it.
OUTER_PASSES = 8
#: Change of every frame gain below which the passes stop.
GAIN_TOLERANCE = 2e-5


def fit_frame_gains(measured: list, model: list) -> tuple[np.ndarray, list]:
    """Gains ``g`` (F,) per frame and the model ``g_n s_q M_n(q)`` (list of (N, P)), from ``measured`` and the
    twin's ``model`` frames (lists of (N, P) per sequence, the pixel gain already in ``model``)."""
    data = np.concatenate(measured, axis=0)  # (F, P)
    base = np.concatenate(model, axis=0)     # (F, P)
    frame_gain = np.ones(data.shape[0])
    pixel_gain = np.ones(data.shape[1])
    for _ in range(ALTERNATIONS):
        m = base * pixel_gain[None, :]
        frame_gain = np.sum(data * m, axis=1) / np.maximum(np.sum(m * m, axis=1), 1e-12)
        m = base * frame_gain[:, None]
        pixel_gain = np.sum(data * m, axis=0) / np.maximum(np.sum(m * m, axis=0), 1e-12)
    mean = float(np.mean(frame_gain))
    frame_gain, pixel_gain = frame_gain / mean, pixel_gain * mean
    fitted = base * frame_gain[:, None] * pixel_gain[None, :]
    out, start = [], 0
    for m in model:
        out.append(fitted[start:start + m.shape[0]])
        start += m.shape[0]
    return frame_gain, out


def _drift_law(frame_gain: np.ndarray, steps: list) -> tuple[float, float, np.ndarray]:
    """``rate``, ``sigma`` and the relative departures (F,) of the frame gains from ``a (1 + rate m)``."""
    m = np.concatenate([np.arange(s, dtype=np.float64) for s in steps])
    design = np.column_stack([np.ones_like(m), m])
    (a, b), *_ = np.linalg.lstsq(design, frame_gain, rcond=None)
    trend = a + b * m
    departure = frame_gain / trend - 1.0
    dof = max(frame_gain.size - 2, 1)
    return float(b / a), float(np.sqrt(np.sum(departure ** 2) / dof)), departure


def fit_drift_with_flicker(pixels: PixelSet, drift_entry: dict, *, base=(), refine: int = 1,
                           rss_before: float) -> dict:
    """The ``intensity_drift`` entry: ``drift_entry`` (the drift alone, fitted as one parameter) or, when the
    frames share a random gain, the per-frame model with ``rate_per_frame`` and ``sigma`` (module docstring)."""
    n = pixels.values
    frames = sum(s.steps for s in pixels.sequences)
    rss_drift = (drift_entry["residual_after"] ** 2) * n
    frame_gain = np.ones(frames)
    for iteration in range(OUTER_PASSES):  # the twin's phase offsets, refitted on the frames unflickered
        split = np.split(frame_gain, np.cumsum([s.steps for s in pixels.sequences])[:-1])
        steady = replace(pixels, measured=[m / g[:, None] for m, g in zip(pixels.measured, split)])
        _, _, model = intensity_residual(steady, list(base), refine=refine)
        previous = frame_gain
        frame_gain, fitted = fit_frame_gains(pixels.measured, model)
        rss = float(sum(np.sum((m - f) ** 2) for m, f in zip(pixels.measured, fitted)))
        over_drift = delta_bic(rss_drift, rss, n, frames - 2)
        if (iteration == 0 and over_drift <= 0.0) or np.max(np.abs(frame_gain - previous)) < GAIN_TOLERANCE:
            break  # no flicker to speak of, or converged
    drift_entry["evidence"]["flicker_delta_bic_over_drift"] = over_drift
    if over_drift <= MIN_DELTA_BIC:
        return drift_entry
    rate, sigma, departure = _drift_law(frame_gain, [s.steps for s in pixels.sequences])
    before, after = float(np.sqrt(rss_before / n)), float(np.sqrt(rss / n))
    parameters = {"rate_per_frame": rate, "sigma": sigma}
    return {"name": "intensity_drift", "parameters": parameters, "residual_before": before,
            "residual_after": after, "gain": gain(before, after),
            "evidence": {"domain": "intensity", "unit": "DN", "values": n, "parameters": frames - 1,
                         "delta_bic": delta_bic(rss_before, rss, n, frames - 1), "model": "per-frame gain (flicker)",
                         "flicker_delta_bic_over_drift": over_drift,
                         "frame_gains": [float(f"{g:.6g}") for g in frame_gain],
                         "sigma_relative_standard_error": float(1.0 / np.sqrt(2.0 * max(frames - 2, 1))),
                         "flicker_departures": [float(f"{d:.4g}") for d in departure]}}
