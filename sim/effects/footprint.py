"""Geometry-stage effect ``pixel_footprint``: each camera pixel integrates the scene over its area and the lens'
blur, so pixels on a silhouette or a depth edge mix surfaces.

The renderer traces ``samples x samples`` rays per pixel (a regular grid over the pixel's area), renders their
frames (pattern and geometry stages), blurs them by a Gaussian of ``blur_sigma_px`` camera pixels (the lens'
point-spread function, on the fine grid: ``samples * blur_sigma_px`` fine pixels) and averages each pixel's
samples (a box over its area); the camera-stage effects then act on the pixel's frames (noise after the
integration). On a smooth surface the mixture moves a pixel's phase by the blur's curvature term only; where the
surface ends, the pixel holds light from both sides, less modulation, and a phase pulled towards the neighbour.
"""
from __future__ import annotations

import numpy as np

from .camera import gaussian_blur
from .registry import find_effect

__all__ = ["integrate_footprint", "footprint_samples"]


def footprint_samples(effects) -> int:
    """Rays per pixel and axis the ``pixel_footprint`` effect asks for (1 without it)."""
    effect = find_effect(effects, "pixel_footprint")
    return 1 if effect is None else max(int(effect["samples"]), 1)


def integrate_footprint(fine_frames: np.ndarray, samples: int, blur_sigma_px: float) -> np.ndarray:
    """Frames (N, H, W) of pixels integrating ``fine_frames`` (N, H * samples, W * samples) over the lens blur
    (``blur_sigma_px`` camera pixels) and their area (a ``samples x samples`` box)."""
    fine = np.asarray(fine_frames, dtype=np.float64)
    if fine.ndim != 3 or fine.shape[1] % samples or fine.shape[2] % samples:
        raise ValueError(f"fine_frames must have shape (N, H*{samples}, W*{samples}); got {fine.shape}")
    if blur_sigma_px > 0:
        fine = np.stack([gaussian_blur(frame, blur_sigma_px * samples) for frame in fine])
    n, height, width = fine.shape
    return fine.reshape(n, height // samples, samples, width // samples, samples).mean(axis=(2, 4))
