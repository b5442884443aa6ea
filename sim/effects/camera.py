"""Camera-stage effects on float frames in digital numbers (DN), before the final quantization.

Applied in this order to each frame ``I`` (``FS = 2^bit_depth - 1``):

- ``ambient_light``: ``I += FS * exposure * (level * albedo)`` on surfaces, ``+ FS * background`` everywhere:
  the background ``A`` rises, the modulation ``B`` is unchanged, the phase is unchanged;
- ``vignetting``: ``I *= 1 + k1 r^2 + k2 r^4``, ``r`` = distance to the image centre over the half diagonal:
  ``A`` and ``B`` scale together, the phase is unchanged;
- ``camera_defocus``: Gaussian blur of sigma ``s`` camera pixels: a fringe of period ``P`` camera pixels loses
  modulation by ``exp(-2 pi^2 s^2 / P^2)``; at depth edges phases mix;
- ``intensity_drift``: frame ``n`` of each sequence ``*= (1 + rate n)(1 + sigma z_n)``: a phase error with the
  period of the fringe (first harmonic of the error in ``theta``);
- ``sensor_noise``: ``I -> gain Poisson((I + dark) / gain) + N(0, read^2)``: variance ``gain (I + dark) +
  read^2`` DN^2; the wrapped-phase noise is ``sqrt(2 / N) sigma / B`` (Eq. (2) least squares);
- ``saturation``: ``I *= exposure_gain`` then ``I = min(I, level FS)``: flat tops, harmonics in the phase where
  clipped; pixels at full scale are flagged by the decoders.

The final quantization ``clip(round(I), 0, FS)`` to ``bit_depth`` is part of every render, not an effect.
"""
from __future__ import annotations

import cv2
import numpy as np

from .registry import find_effect

__all__ = ["apply_camera_effects", "vignetting_factor", "gaussian_blur"]


def vignetting_factor(shape, k1: float, k2: float, *, rows=None, cols=None) -> np.ndarray:
    """``1 + k1 r^2 + k2 r^4`` (H, W), ``r`` = distance from the image centre over the half diagonal; with
    ``rows`` and ``cols`` (P,) only at those pixels of an image of ``shape`` (P,)."""
    height, width = shape
    if rows is None:
        v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    else:
        v, u = np.asarray(rows, np.float64), np.asarray(cols, np.float64)
    r2 = ((u - (width - 1) / 2.0) ** 2 + (v - (height - 1) / 2.0) ** 2) / ((width / 2.0) ** 2 + (height / 2.0) ** 2)
    return 1.0 + k1 * r2 + k2 * r2 * r2


def gaussian_blur(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian blur (H, W) with reflecting borders (OpenCV, kernel +-4 sigma)."""
    if sigma_px <= 0:
        return image
    radius = max(int(np.ceil(4.0 * sigma_px)), 1)
    return cv2.GaussianBlur(image, (2 * radius + 1, 2 * radius + 1), sigmaX=sigma_px, sigmaY=sigma_px,
                            borderType=cv2.BORDER_REFLECT)


def apply_camera_effects(frames: np.ndarray, *, effects, albedo, hit, full_scale: float, exposure: float,
                         rng, vignetting_map=None) -> np.ndarray:
    """Camera-stage effects on one sequence's float frames (N, H, W), DN; returns a new array.

    ``albedo`` (H, W) and ``hit`` (H, W) are the surface samples' (for ambient light); ``rng`` a numpy Generator
    (noise, drift jitter); ``vignetting_map`` (H, W), optional, the ``vignetting`` factor when the frames are not
    the whole image (a list of pixels: :func:`vignetting_factor` with ``rows, cols``).
    """
    frames = np.array(frames, dtype=np.float64, copy=True)
    effect = find_effect(effects, "ambient_light")
    if effect is not None:
        frames += full_scale * (exposure * effect["level"] * np.where(hit, albedo, 0.0) + effect["background"])
    effect = find_effect(effects, "vignetting")
    if effect is not None:
        frames *= (vignetting_factor(frames.shape[1:], effect["k1"], effect["k2"]) if vignetting_map is None
                   else vignetting_map)
    effect = find_effect(effects, "camera_defocus")
    if effect is not None and effect["sigma_px"] > 0:
        for n in range(len(frames)):
            frames[n] = gaussian_blur(frames[n], effect["sigma_px"])
    effect = find_effect(effects, "intensity_drift")
    if effect is not None:
        frame_index = np.arange(len(frames))
        factor = 1.0 + effect["rate_per_frame"] * frame_index
        if effect["sigma"] > 0:
            factor = factor * (1.0 + effect["sigma"] * rng.normal(size=len(frames)))
        frames *= factor[:, None, None]
    effect = find_effect(effects, "sensor_noise")
    if effect is not None:
        gain = effect["gain_dn_per_electron"]
        signal = np.clip(frames + effect["dark_dn"], 0.0, None)
        if gain > 0:
            frames = gain * rng.poisson(signal / gain).astype(np.float64)
        else:
            frames = signal
        if effect["read_noise_dn"] > 0:
            frames += rng.normal(0.0, effect["read_noise_dn"], frames.shape)
    effect = find_effect(effects, "saturation")
    if effect is not None:
        frames = np.minimum(frames * effect["exposure_gain"], effect["level"] * full_scale)
    return frames
