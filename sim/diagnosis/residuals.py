"""Decomposition of what the twin gets wrong into components with a physical reading.

Phase residual (measured - twin projector coordinate, projector px), removed one after the other:

- ``low_order``: a quadratic in the image coordinates (pose and calibration errors), normalized to [-1, 1];
- ``radial``: ``a r^4 + b r^6`` about the image centre, their part orthogonal to the quadratic (``r^2`` is in
  it): lens distortion the calibration lacks;
- ``periodic``: the mean in 32 bins of the wrapped phase ``theta = 2 pi f x / W mod 2 pi``, with its harmonic
  amplitudes (gamma with few steps: harmonic N; drift: 1; step errors: 2);
- ``pixel_pitch``: the mean in 16 bins of the projector coordinate's fractional part (pixelation);
- ``edge_band``: the RMS within 2 px of the valid region's border against the interior's (the low-order and
  radial parts are fitted on the interior only);
- ``random``: what is left: RMS and the correlation of horizontal neighbours (0 for white noise).

Intensity residual (measured - twin frames, DN), per value of the photometric fit: ``per_frame`` mean relative
to the model's mean (drift), ``periodic`` over the pattern angle ``theta + delta_n`` normalized by the pixel's
modulation (harmonics of the pattern: gamma, saturation), ``by_level`` over the model level (nonlinearity,
ambient, clipping) and the ``random`` remainder.
"""
from __future__ import annotations

from typing import Any

import cv2
import numpy as np

__all__ = ["decompose_phase", "decompose_intensity", "harmonics"]

PHASE_BINS = 32
PITCH_BINS = 16


def _binned_mean(values, index, bins):
    counts = np.bincount(index, minlength=bins)
    return np.bincount(index, weights=values, minlength=bins) / np.maximum(counts, 1), counts


def harmonics(profile: np.ndarray, count: int = 4) -> list:
    """Amplitudes of harmonics 1..count of a profile sampled uniformly over one period."""
    spectrum = np.fft.rfft(profile) / len(profile)
    return [float(2.0 * abs(spectrum[k])) for k in range(1, count + 1)]


def _harmonics_lsq(values: np.ndarray, theta: np.ndarray, count: int = 4) -> list:
    """Amplitudes of harmonics 1..count of ``values`` against the angle ``theta`` (least squares on every
    value, so an uneven sampling of the angle does not bias them)."""
    design = np.column_stack([np.ones_like(theta)] + [f(k * theta) for k in range(1, count + 1)
                                                      for f in (np.cos, np.sin)])
    coefficients, *_ = np.linalg.lstsq(design, values, rcond=None)
    return [float(np.hypot(coefficients[2 * k - 1], coefficients[2 * k])) for k in range(1, count + 1)]


def _rms(values) -> float:
    values = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.mean(values ** 2))) if values.size else float("nan")


def _edge_band(mask: np.ndarray, width: int = 2) -> np.ndarray:
    kernel = np.ones((2 * width + 1, 2 * width + 1), np.uint8)
    eroded = cv2.erode(mask.astype(np.uint8), kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
    return mask & ~eroded


def decompose_phase(residual_px: np.ndarray, projector_x: np.ndarray, *, frequency: float, extent: float) -> dict:
    """Components (module docstring) of a phase residual map (H, W) (NaN = not fitted): ``stats`` (JSON) and
    ``maps`` (H, W each, for the figure)."""
    mask = np.isfinite(residual_px) & np.isfinite(projector_x)
    height, width = residual_px.shape
    v, u = np.nonzero(mask)
    r = residual_px[mask]
    maps: dict[str, np.ndarray] = {}
    stats: dict[str, Any] = {"pixels": int(mask.sum()), "total_rms_px": _rms(r)}
    if len(r) < 10:
        return {"stats": stats, "maps": maps}
    x = (u - (width - 1) / 2.0) / (width / 2.0)
    y = (v - (height - 1) / 2.0) / (height / 2.0)

    def _store(name, component):
        image = np.full((height, width), np.nan)
        image[mask] = component
        maps[name] = image
        stats[f"{name}_rms_px"] = _rms(component)

    # the quadratic first; then the radial terms' part orthogonal to it (on a small region r^4 is nearly a
    # quadratic: a joint fit would split one shape into two large cancelling parts)
    rho2 = x * x + y * y
    quadratic = np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])
    radial = np.column_stack([rho2 ** 2, rho2 ** 3])
    inner = ~_edge_band(mask)[mask]  # smooth components are fitted on the interior (the rim is its own part)
    low_part = quadratic @ np.linalg.lstsq(quadratic[inner], r[inner], rcond=None)[0]
    radial = radial - quadratic @ np.linalg.lstsq(quadratic[inner], radial[inner], rcond=None)[0]
    radial_part = radial @ np.linalg.lstsq(radial[inner], (r - low_part)[inner], rcond=1e-10)[0]
    r = r - low_part - radial_part
    _store("low_order", low_part)
    _store("radial", radial_part)
    theta = np.mod(2.0 * np.pi * frequency * projector_x[mask] / extent, 2.0 * np.pi)
    index = np.minimum((theta / (2.0 * np.pi) * PHASE_BINS).astype(int), PHASE_BINS - 1)
    stats["periodic_harmonics_px"] = _harmonics_lsq(r, theta)
    profile, _ = _binned_mean(r, index, PHASE_BINS)
    r = r - profile[index]
    _store("periodic", profile[index])
    stats["periodic_profile_px"] = [float(p) for p in profile]
    fraction = np.mod(projector_x[mask] + 0.5, 1.0)
    index = np.minimum((fraction * PITCH_BINS).astype(int), PITCH_BINS - 1)
    profile, _ = _binned_mean(r, index, PITCH_BINS)
    r = r - profile[index]
    _store("pixel_pitch", profile[index])
    edge = _edge_band(mask)[mask]
    stats["edge_band_rms_px"] = _rms(r[edge])
    stats["interior_rms_px"] = _rms(r[~edge])
    _store("random", r)
    image = maps["random"]
    pairs = np.isfinite(image[:, 1:]) & np.isfinite(image[:, :-1])
    a, b = image[:, 1:][pairs], image[:, :-1][pairs]
    stats["random_neighbour_correlation"] = float(np.corrcoef(a, b)[0, 1]) if len(a) > 10 else float("nan")
    return {"stats": stats, "maps": maps}


def decompose_intensity(pixels, residual: list, model: list) -> dict:
    """Components (module docstring) of an intensity residual (lists of (N, P) per sequence)."""
    stats: dict[str, Any] = {"values": int(sum(r.size for r in residual)),
                             "total_rms_dn": _rms(np.concatenate([r.ravel() for r in residual]))}
    per_frame, periodic, random_parts = [], {}, []
    level_values, level_residual = [], []
    for sequence, coord, res, mod in zip(pixels.sequences, pixels.coords, residual, model):
        mean_model = mod.mean(axis=1)
        per_frame += [float(v) for v in res.mean(axis=1) / np.maximum(mean_model, 1e-9)]
        res = res - res.mean(axis=1, keepdims=True)
        modulation = np.maximum(0.5 * (mod.max(axis=0) - mod.min(axis=0)), 1e-9)  # (P,)
        n = np.arange(sequence.steps)[:, None]
        angle = (2.0 * np.pi * sequence.frequency * coord[None, :] / pixels.extent + sequence.phase_offset
                 + sequence.shift_sign * 2.0 * np.pi * n / sequence.steps)
        index = np.minimum((np.mod(angle, 2.0 * np.pi) / (2.0 * np.pi) * PHASE_BINS).astype(int), PHASE_BINS - 1)
        normalized = res / modulation[None, :]
        profile, _ = _binned_mean(normalized.ravel(), index.ravel(), PHASE_BINS)
        periodic[f"{sequence.frequency:g}x{sequence.steps}"] = {
            "profile": [float(p) for p in profile], "harmonics_relative": harmonics(profile)}
        random_parts.append((normalized - profile[index]) * modulation[None, :])
        level_values.append(mod.ravel())
        level_residual.append(res.ravel())
    stats["per_frame_relative"] = per_frame
    stats["periodic"] = periodic
    levels = np.concatenate(level_values)
    values = np.concatenate(level_residual)
    edges = np.quantile(levels, np.linspace(0, 1, 17))
    index = np.clip(np.searchsorted(edges, levels, side="right") - 1, 0, 15)
    profile, _ = _binned_mean(values, index, 16)
    stats["by_level"] = {"level_dn": [float(0.5 * (a + b)) for a, b in zip(edges[:-1], edges[1:])],
                         "mean_residual_dn": [float(p) for p in profile]}
    stats["random_rms_dn"] = _rms(np.concatenate([r.ravel() for r in random_parts]))
    return {"stats": stats}
