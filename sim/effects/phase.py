"""Phase-stage effects: inside the phase pipeline, never applied to frames.

``phase_filter``: the wrapped phase is smoothed as a unit phasor: ``psi' = atan2(G*(m sin psi), G*(m cos psi))``
with ``G`` a Gaussian of ``sigma_px`` camera pixels and ``m`` the valid mask (normalized convolution). A linear
phase ramp is kept exactly away from edges; white phase noise of standard deviation ``s`` (small) falls to about
``s / (2 sqrt(pi) sigma)``; steps and fringe-order edges are smeared over ~``2 sigma`` pixels.
"""
from __future__ import annotations

import numpy as np

from .camera import gaussian_blur
from .registry import find_effect

__all__ = ["phase_filter", "apply_phase_effects"]


def phase_filter(wrapped_phase: np.ndarray, sigma_px: float, valid=None) -> np.ndarray:
    """Smoothed wrapped phase (H, W) in [0, 2 pi); NaN stays NaN, ``valid`` (H, W) bool masks the neighbours."""
    psi = np.asarray(wrapped_phase, dtype=np.float64)
    if psi.ndim != 2:
        raise ValueError(f"wrapped_phase must have shape (H, W); got {psi.shape}")
    mask = np.isfinite(psi) if valid is None else (np.asarray(valid, bool) & np.isfinite(psi))
    cos = gaussian_blur(np.where(mask, np.cos(psi), 0.0), sigma_px)
    sin = gaussian_blur(np.where(mask, np.sin(psi), 0.0), sigma_px)
    out = np.mod(np.arctan2(sin, cos), 2.0 * np.pi)
    return np.where(mask, out, np.nan)


def apply_phase_effects(wrapped_phase: np.ndarray, effects, valid=None) -> np.ndarray:
    """The phase-stage effects of ``effects`` applied to a wrapped phase map (H, W)."""
    effect = find_effect(effects, "phase_filter")
    if effect is None:
        return wrapped_phase
    return phase_filter(wrapped_phase, effect["sigma_px"], valid)
