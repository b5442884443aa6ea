"""Pattern-stage effects: what the projector casts, as a function of the continuous projector coordinate.

The ideal projector casts ``p_n(c) = offset + amplitude cos(theta_n(c))`` with ``theta_n = 2 pi f c / W +
phase_offset + sign 2 pi n / N`` (the paper's Eq. (1); ``c`` the coordinate along the fringe axis). The stage's
effects, in this order:

- ``phase_shift_error``: ``theta_n`` gets ``sign * (scale - 1) * 2 pi n / N + errors_rad[n] + sigma_rad z_n``;
- ``projector_pixelation``: ``c -> round(c)`` (the level of the micromirror under the point) and the level
  ``p -> round(p (2^b - 1)) / (2^b - 1)``;
- ``projector_gamma``: ``p -> p ** gamma``;
- ``projector_response``: ``p -> L(p)``, a monotone piecewise-linear lookup table (knots evenly spaced on [0, 1]);
- ``projector_defocus``: Gaussian blur along the fringe axis of sigma ``s`` projector pixels: harmonic ``k`` of
  the (periodic) pattern is multiplied by ``exp(-k^2 (2 pi f s / W)^2 / 2) = exp(-2 pi^2 s^2 k^2 f^2 / W^2)``.

With defocus the pattern is evaluated from its Fourier series in ``theta`` (exact for any pointwise chain);
otherwise pointwise.
"""
from __future__ import annotations

import numpy as np

from .registry import find_effect

__all__ = ["step_shifts", "pattern_levels", "defocus_attenuation", "projector_images", "response_levels",
           "FOURIER_SAMPLES"]

#: Samples of one period used for the Fourier series of a pointwise pattern chain.
FOURIER_SAMPLES = 1024


def step_shifts(steps: int, shift_sign: int, effects, rng) -> np.ndarray:
    """Phase shift (N,) of each step in radians: ``sign 2 pi n / N`` with the ``phase_shift_error`` effect."""
    n = np.arange(steps)
    shifts = shift_sign * 2.0 * np.pi * n / steps
    effect = find_effect(effects, "phase_shift_error")
    if effect is not None:
        shifts = shifts * effect["scale"]
        errors = np.asarray(effect["errors_rad"], dtype=np.float64)
        if errors.size:
            if errors.size != steps:
                raise ValueError(f"phase_shift_error.errors_rad must hold one error per step ({steps}); "
                                 f"got {errors.size}")
            shifts = shifts + errors
        if effect["sigma_rad"] > 0:
            shifts = shifts + rng.normal(0.0, effect["sigma_rad"], steps)
    return shifts


def defocus_attenuation(sigma_px, frequency: float, extent: float, harmonic: int = 1):
    """Factor on harmonic ``k`` of a fringe of ``frequency`` periods per ``extent`` px blurred by a Gaussian of
    ``sigma_px``: ``exp(-2 pi^2 sigma^2 k^2 f^2 / W^2)``."""
    return np.exp(-2.0 * np.pi ** 2 * np.square(sigma_px) * (harmonic * frequency / extent) ** 2)


def _pointwise(levels, effects):
    pixelation = find_effect(effects, "projector_pixelation")
    if pixelation is not None and pixelation["quantize_bits"] > 0:
        full = float(2 ** pixelation["quantize_bits"] - 1)
        levels = np.round(levels * full) / full
    gamma = find_effect(effects, "projector_gamma")
    if gamma is not None:
        levels = np.power(np.clip(levels, 0.0, None), gamma["gamma"])
    response = find_effect(effects, "projector_response")
    if response is not None:
        levels = response_levels(levels, response["levels"])
    return levels


def response_levels(levels, knots) -> np.ndarray:
    """``projector_response``: the piecewise-linear table ``knots`` (K,) at inputs ``k / (K - 1)`` applied to
    ``levels`` (any shape, fractions of full scale; inputs outside [0, 1] take the end values)."""
    knots = np.asarray(knots, dtype=np.float64)
    return np.interp(levels, np.linspace(0.0, 1.0, len(knots)), knots)


def defocus_sigma_px(effects, projector_depth):
    """Projector blur sigma (projector pixels) per point, or None without ``projector_defocus``."""
    effect = find_effect(effects, "projector_defocus")
    if effect is None:
        return None
    sigma = np.full(np.shape(projector_depth), effect["sigma_px"])
    if effect["focus_distance"] > 0:
        sigma = sigma + effect["sigma_px_per_unit"] * np.abs(np.asarray(projector_depth) - effect["focus_distance"])
    return sigma


def pattern_levels(coord, *, frequency: float, extent: float, shift: float | np.ndarray, offset: float,
                   amplitude: float, phase_offset: float = 0.0, effects=(), sigma_px=None) -> np.ndarray:
    """Projected level in [0, 1] (fraction of full scale) at projector coordinates ``coord`` (any shape).

    Parameters
    ----------
    coord : ndarray
        Projector coordinate along the fringe axis, projector pixels (0-based centres).
    frequency, extent : float
        ``f`` periods across ``W = extent`` pixels.
    shift : float or ndarray
        Phase shift of this step, radians (from :func:`step_shifts`); an array broadcast against ``coord``
        (e.g. (N, 1) against (1, P)) evaluates several steps at once.
    offset, amplitude : float
        Ideal level ``offset + amplitude cos(theta)``.
    effects : tuple of Effect
        Parsed effects; only the pattern stage is used.
    sigma_px : ndarray or None
        Per-point defocus sigma (:func:`defocus_sigma_px`), same shape as ``coord``.
    """
    coord = np.asarray(coord, dtype=np.float64)
    pixelation = find_effect(effects, "projector_pixelation")
    if pixelation is not None:
        coord = np.round(coord)
    theta = 2.0 * np.pi * frequency * coord / extent + phase_offset + shift
    if sigma_px is None:
        return _pointwise(offset + amplitude * np.cos(theta), effects)
    samples = np.linspace(0.0, 2.0 * np.pi, FOURIER_SAMPLES, endpoint=False)
    profile = _pointwise(offset + amplitude * np.cos(samples), effects)
    coefficients = np.fft.rfft(profile) / FOURIER_SAMPLES  # even profile: real cosine coefficients
    cosine = 2.0 * coefficients.real
    cosine[0] = coefficients[0].real
    scale = np.abs(cosine).max()
    sigma_theta = 2.0 * np.pi * frequency * np.asarray(sigma_px, dtype=np.float64) / extent
    result = np.full(theta.shape, cosine[0])
    for k in range(1, FOURIER_SAMPLES // 2):
        if abs(cosine[k]) < 1e-9 * scale:
            continue
        attenuation = np.exp(-0.5 * (k * sigma_theta) ** 2)
        if np.all(attenuation * abs(cosine[k]) < 1e-9 * scale):
            continue
        result += cosine[k] * attenuation * np.cos(k * theta)
    return result


def projector_images(*, frequency: float, steps: int, axis: str, shift_sign: int, projector_size, offset: float,
                     amplitude: float, phase_offset: float = 0.0, effects=(), rng=None) -> np.ndarray:
    """The projector's images (N, Hp, Wp) in [0, 1] with the pattern-stage effects, for a renderer that projects
    pixel images (Blender): each micromirror shows the level at its centre, so ``projector_pixelation``'s rounding
    is built in; ``projector_defocus`` blurs along the fringe axis with its constant ``sigma_px`` (a depth-dependent
    focus needs the raycast engine)."""
    defocus = find_effect(effects, "projector_defocus")
    if defocus is not None and defocus["focus_distance"] > 0:
        raise ValueError("projector_defocus with focus_distance > 0 (depth-dependent blur) is raycast-only; "
                         "use engine='raycast' or a constant sigma_px")
    width, height = projector_size
    extent = width if axis == "x" else height
    coord = np.arange(extent, dtype=np.float64)
    sigma = None if defocus is None else np.full(extent, defocus["sigma_px"])
    shifts = step_shifts(steps, shift_sign, effects, rng if rng is not None else np.random.default_rng(0))
    images = np.empty((steps, height, width))
    for n in range(steps):
        profile = pattern_levels(coord, frequency=frequency, extent=extent, shift=shifts[n], offset=offset,
                                 amplitude=amplitude, phase_offset=phase_offset, effects=effects, sigma_px=sigma)
        images[n] = profile[None, :] if axis == "x" else profile[:, None]
    return images

