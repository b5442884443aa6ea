"""Each pixel's phase noise, measured from its own N-step fit, and the pixels far noisier than the rest of the scan.

An N-step sequence (``N >= 4``) over-determines the fringe model ``I_n = A + B cos(psi + delta_n)`` (Eq. (1)): three
parameters fitted to ``N`` images leave a residual whose mean square over the steps is, because the steps are
equally spaced over a full turn (the model's terms are orthogonal),

    R^2 = mean_n I_n^2 - A^2 - B^2 / 2,

``(N - 3) / N`` times the variance ``sigma^2`` of the image noise. The least-squares phase of Eq. (2) has the
standard deviation ``sqrt(2 / N) sigma / B``, so each pixel measures its own phase noise,

    sigma_psi = sqrt(2 / (N - 3)) R / B                 (radians),

whatever the noise's cause: camera noise over a dark or glossy surface, path-tracing noise of a rendered scene where
most light arrives indirectly, flicker, motion. A pixel whose ``sigma_psi`` is :data:`DEFAULT_MAX_NOISE_RATIO` times
the scan's median or more (:func:`noise_outliers`) is dropped: its point may lie several of the scan's typical depth
noise off the surface, which a grasp cannot tell from the surface. The ratio, not a level, sets the bound: a noisy
rig keeps its typical pixels; a pixel is judged against the scan it belongs to. Only sequences of at least
:data:`MIN_NOISE_STEPS` steps are judged: three leave no residual (``N - 3 = 0``), four leave one degree of freedom,
a single draw of the noise (``5 x`` its median is 3.4 of its standard deviations: 0.08 % of a clean surface would
go); from five on (two or more degrees of freedom) a clean surface loses nothing (below ``1e-7`` at 5 steps).
The two frequencies' agreement (:mod:`dptpu.fpp.frequency_consistency`) is the check that needs no extra steps.

**The camera's quantization** sets a floor under every pixel's phase noise: rounding to whole digital numbers adds
noise of variance ``1 / 12`` (DN^2) to each image, so a pixel of modulation ``B`` has at least

    sigma_q = sqrt(2 / N) / (sqrt(12) B)                (radians, :func:`quantization_phase_noise`)

even where the camera adds nothing else. On a clean capture (little camera noise) the scan's median is close to
``sigma_q`` of the median modulation, so every pixel whose modulation is a fifth of the median (dim texture, a
surface turned away from the projector) would reach 5 times the median from quantization alone, with a phase as
good as its modulation allows. :func:`noise_outliers` therefore judges a pixel against ``max_ratio`` times the larger
of the scan's median and the pixel's own ``sigma_q``: a pixel is an outlier only when its noise is also far above
what its modulation's quantization explains. Where the camera's noise is several DN this floor lies far below the
median and changes nothing.

A projector whose response is not linear (gamma) adds harmonics of the pattern, which 12 steps see in the residual:
``R`` then grows with ``B`` at every pixel alike, so ``R / B`` and the ratio to the median stay unchanged.
"""
from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from .bracketed_median import bracketed_median

__all__ = ["DEFAULT_MAX_NOISE_RATIO", "MIN_NOISE_STEPS", "fit_residual", "noise_outliers", "phase_noise",
           "quantization_phase_noise", "sequence_phase_noise"]

#: A pixel whose phase noise is this many times the scan's median (in any sequence of 5 or more steps) is dropped.
#: Chosen on the main job's shipped scenes (docs/nodes.md, "Phase noise"): at 5 the path-traced scene random-1 lost
#: 43 of its 88 wrong points for 0.9 % of its right ones; the twin's captures with camera noise lose the pixels of
#: less than a fifth of the median modulation.
DEFAULT_MAX_NOISE_RATIO = 5.0
#: Fewest steps of a sequence whose residual is judged (module docstring).
MIN_NOISE_STEPS = 5


def fit_residual(images: np.ndarray, background: np.ndarray, modulation: np.ndarray) -> np.ndarray:
    """RMS residual ``R`` (H, W) float32 of the N-step fit (module docstring), the images' units.

    Parameters
    ----------
    images : ndarray (N, H, W)
        The sequence's images, ``N >= 3`` equally spaced steps over a full turn.
    background, modulation : ndarray (H, W)
        ``A`` and ``B`` of the fit (:func:`dptpu.fpp.phase.wrapped_phase`).
    """
    return _rms_residual64(images, background, modulation).astype(np.float32)


def _rms_residual64(images: np.ndarray, background: np.ndarray, modulation: np.ndarray) -> np.ndarray:
    """:func:`fit_residual` before its rounding to float32: ``R`` (H, W) float64, a buffer the caller may reuse."""
    images = np.asarray(images)
    if images.ndim != 3 or images.shape[0] < 3:
        raise ValueError(f"images must be an (N, H, W) stack with N >= 3; got shape {images.shape}")
    # float64: R^2 (~0.06 DN^2 on a clean 8-bit capture) is the difference of terms of up to 6.5e4 DN^2, whose
    # float32 rounding (up to 4e-3 DN^2) would be a tenth of it. In place: one float64 buffer and one temporary
    a = np.asarray(background)
    b = np.asarray(modulation)
    residual = np.divide(_sum_of_squares(images), float(images.shape[0]), dtype=np.float64)  # mean_n I_n^2
    term = np.multiply(a, a, dtype=np.float64)
    residual -= term  # - A^2
    np.multiply(b, 0.5, out=term, dtype=np.float64)
    term *= b
    residual -= term  # - B^2 / 2
    np.maximum(residual, 0.0, out=residual)
    return np.sqrt(residual, out=residual)


def _sum_of_squares(images: np.ndarray) -> np.ndarray:
    """``sum_n I_n^2`` (H, W): float32 where that is exact, float64 otherwise. OpenCV's accumulator for the
    camera's dtypes (exact in float32 for 8-bit frames of up to 258 steps, float64 otherwise), numpy for the
    others."""
    if images.dtype in (np.uint8, np.uint16, np.float32, np.float64):
        exact32 = images.dtype == np.uint8 and images.shape[0] <= 258  # 258 * 255^2 < 2^24
        total = np.zeros(images.shape[1:], np.float32 if exact32 else np.float64)
        for image in images:
            cv2.accumulateSquare(np.ascontiguousarray(image), total)
        return total  # float32 where exact: the caller's float64 arithmetic converts it as it reads it
    as_float = images.astype(np.float64)
    return np.einsum("nhw,nhw->hw", as_float, as_float)


def phase_noise(residual: np.ndarray, modulation: np.ndarray, steps: int) -> np.ndarray | None:
    """``sigma_psi = sqrt(2 / (N - 3)) R / B`` (H, W) float32, radians (inf where ``B`` is 0); None for fewer than
    :data:`MIN_NOISE_STEPS` steps (module docstring)."""
    if steps < 3:
        raise ValueError(f"steps must be >= 3; got {steps}")
    if steps < MIN_NOISE_STEPS:
        return None
    return _phase_noise_into(np.empty(np.shape(residual)), residual, modulation, steps)


def _phase_noise_into(buffer: np.ndarray, residual: np.ndarray, modulation: np.ndarray, steps: int) -> np.ndarray:
    """:func:`phase_noise` computed in the float64 ``buffer`` (H, W) (overwritten; may be ``residual``'s own float64
    buffer once ``residual`` is its float32 rounding)."""
    with np.errstate(divide="ignore", invalid="ignore"):  # float64 arithmetic in one buffer, rounded once
        noise = np.multiply(residual, np.sqrt(2.0 / (steps - 3)), out=buffer, dtype=np.float64)
        np.divide(noise, modulation, out=noise, dtype=np.float64)
    np.copyto(noise, np.inf, where=np.isnan(noise))
    return noise.astype(np.float32)


def quantization_phase_noise(modulation: np.ndarray, steps: int, images_dtype) -> np.ndarray | None:
    """``sigma_q = sqrt(2 / N) / (sqrt(12) B)`` (H, W) float32, radians: the phase noise that rounding integer images
    to whole digital numbers leaves at modulation ``B`` (module docstring); None for float images (no rounding).

    Parameters
    ----------
    modulation : ndarray (H, W)
        ``B`` of the fit, digital numbers.
    steps : int
        ``N`` of the sequence.
    images_dtype : numpy dtype
        The images' dtype: the floor holds for integer images only.
    """
    if not np.issubdtype(np.dtype(images_dtype), np.integer):
        return None
    with np.errstate(divide="ignore"):  # one float32 division: on the phase node's path
        return np.float32(np.sqrt(2.0 / steps) / np.sqrt(12.0)) / np.asarray(modulation, np.float32)


def sequence_phase_noise(images: np.ndarray, background: np.ndarray, modulation: np.ndarray, *,
                         measure: bool = True) -> tuple[np.ndarray | None, np.ndarray | None]:
    """One sequence's phase noise and its quantization floor, ``(sigma_psi, sigma_q)`` (module docstring): what
    :func:`noise_outliers` judges a sequence by.

    Parameters
    ----------
    images : ndarray (N, H, W)
        The sequence's images.
    background, modulation : ndarray (H, W)
        ``A`` and ``B`` of the fit (:func:`dptpu.fpp.phase.wrapped_phase`).
    measure : bool
        False: the floor only (no residual computed; the noise test off).

    Returns
    -------
    sigma_psi : ndarray (H, W) float32 or None
        :func:`phase_noise` of the fit's :func:`fit_residual`; None below :data:`MIN_NOISE_STEPS` steps or without
        ``measure``.
    sigma_q : ndarray (H, W) float32 or None
        :func:`quantization_phase_noise`; None for float images.
    """
    steps = np.shape(images)[0]
    floor = quantization_phase_noise(modulation, steps, np.asarray(images).dtype)
    if not measure or steps < MIN_NOISE_STEPS:
        return None, floor
    residual64 = _rms_residual64(images, background, modulation)  # fit_residual's R, rounded to float32 below
    return _phase_noise_into(residual64, residual64.astype(np.float32), modulation, steps), floor


def noise_outliers(noise: Sequence[np.ndarray | None], valid: np.ndarray,
                   max_ratio: float = DEFAULT_MAX_NOISE_RATIO,
                   floors: Sequence[np.ndarray | None] | None = None) -> np.ndarray:
    """Pixels (H, W) bool, among ``valid``, whose phase noise in any sequence is at least ``max_ratio`` times the
    larger of that sequence's median over ``valid`` and the pixel's floor; none when ``max_ratio`` is 0 (the test
    off) or no sequence has a noise map.

    Parameters
    ----------
    noise : sequence of ndarray (H, W) or None
        :func:`phase_noise` of each sequence (None for one of fewer than :data:`MIN_NOISE_STEPS` steps).
    valid : ndarray (H, W) bool
    max_ratio : float
        0 (off) or > 1.
    floors : sequence of ndarray (H, W) or None, optional
        Per sequence, the noise each pixel has whatever the scan (:func:`quantization_phase_noise`); None: none.
    """
    if not (max_ratio == 0 or max_ratio > 1):
        raise ValueError(f"max_noise_ratio must be 0 (off) or > 1; got {max_ratio}")
    floors = [None] * len(noise) if floors is None else list(floors)
    if len(floors) != len(noise):
        raise ValueError(f"floors must hold one entry per noise map; got {len(floors)} for {len(noise)}")
    valid = np.asarray(valid, dtype=bool)
    outliers = np.zeros(valid.shape, dtype=bool)
    if max_ratio == 0 or not valid.any():
        return outliers
    for sigma, floor in zip(noise, floors):
        if sigma is None:
            continue
        median = float(bracketed_median(sigma[valid]))
        if np.isfinite(median) and median > 0:
            bound = median if floor is None else np.maximum(median, floor)
            outliers |= valid & (sigma >= max_ratio * bound)
    return outliers
