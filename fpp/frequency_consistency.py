"""Agreement of a two-frequency capture's two phases at each pixel, once the high frequency's order is decided.

A surface point seen at projector coordinate ``x`` has the absolute phases ``Phi_h = 2 pi f_h x / W`` and
``Phi_l = 2 pi f_l x / W`` (Eq. (3) for each frequency), so the published absolute phase ``Phi_h`` predicts the
low frequency's wrapped phase: ``psi_l = (f_l / f_h) Phi_h`` modulo ``2 pi``. The **consistency residual**

    eps = wrap((f_l / f_h) Phi_h - psi_l),   wrap into (-pi, pi],

is camera noise where the pixel sees one surface lit directly by one projector column. It grows where that model
fails: light bounced between surfaces (interreflection: a second sinusoid of another phase mixed into each
frequency, shifting the two by different amounts), a pixel mixing two surfaces, a wrong order of the high frequency
(``eps`` then jumps by ``2 pi f_l / f_h`` per order; a wrong order of the low one is invisible here), and pixels whose
phase noise is far above the scan's (dark, glossy or shadowed). Each of these puts the published point off the
surface. For MW the rounding margin of the classical order is ``1 - 2 f_h |eps| / 2 pi`` (Eq. (7)), so the classical
method drops such pixels already, with most of the rest of a noisy capture; the network's order does not look at
``eps`` at all.

:func:`frequency_consistency` turns ``|eps|`` into a confidence on the scale of the scan's own noise: ``z = |eps| /
s`` with ``s = 1.4826 median |eps|`` over the valid pixels (the noise's standard deviation, robust against the
outliers it is there to find), and ``1 - z / Z`` clipped to [0, 1] with ``Z`` = :data:`DEFAULT_CONSISTENCY_SCALE`,
so the default confidence threshold 0.2 (:mod:`dptpu.fpp.confidence`) drops ``z >= 0.8 Z`` = 5 robust standard
deviations. No length, frequency or noise level is set: only the scan's own residuals.

**The quantization floor.** On a clean capture (little camera noise) ``s`` is about the residual that rounding the
images to whole digital numbers leaves at the scan's typical modulation, and a pixel of a fifth of that modulation
(dim texture, a surface turned from the projector) reaches ``z = 5`` from rounding alone, its phases as good as its
modulation allows. ``floor`` (:func:`quantization_residual_noise`) gives each pixel the residual's standard
deviation that rounding predicts at its own modulations,

    s_q = sqrt((f_l / f_h)^2 sigma_q,h^2 + sigma_q,l^2),   sigma_q = sqrt(2 / N) / (sqrt(12) B)

(:func:`dptpu.fpp.fringe_noise.quantization_phase_noise` of each frequency's sequence), and the pixel is judged
against ``max(s, s_q)``. Where the camera's noise is a DN or more ``s`` is far above ``s_q`` and nothing changes.
"""
from __future__ import annotations

import numpy as np

from .bracketed_median import bracketed_median
from .fringe_noise import quantization_phase_noise

__all__ = ["DEFAULT_CONSISTENCY_SCALE", "MIN_SIGMA_RAD", "consistency_residual", "frequency_consistency",
           "integer_frames_floor", "quantization_residual_noise"]

#: ``Z`` of the module docstring: the confidence ``1 - z / Z`` is 0.2 (the default threshold) at ``z`` = 5 robust
#: standard deviations of the scan's residual. Chosen on the main job's shipped scenes and the outside rigs of
#: ``dptpu eval cloud`` (docs/nodes.md, "Frequency consistency").
DEFAULT_CONSISTENCY_SCALE = 6.25
#: 1 / Phi^-1(3/4): the median absolute value of a zero-mean normal variable times this is its standard deviation.
MAD_TO_SIGMA = 1.4826
#: Floor of the residual's standard deviation, radians: a noiseless synthetic scan (residuals of rounding only) is
#: judged against 1 mrad, about the phase noise that 8-bit quantization alone leaves at the modulations seen here.
MIN_SIGMA_RAD = 1e-3


def consistency_residual(absolute_high: np.ndarray, wrapped_low: np.ndarray, f_h: float, f_l: float, *,
                         dtype=np.float64) -> np.ndarray:
    """``eps = wrap((f_l / f_h) Phi_h - psi_l)`` (module docstring), radians in ``(-pi, pi]``, NaN where an input is;
    computed in ``dtype`` (float32 keeps ``eps`` within 1e-4 rad of float64's for ``Phi_h`` up to ``2 pi 120``).

    Parameters
    ----------
    absolute_high : ndarray (H, W)
        The published absolute phase of ``f_h``, radians.
    wrapped_low : ndarray (H, W)
        The wrapped phase of ``f_l``, radians.
    f_h, f_l : float
        Periods across the projector (> 0).
    """
    if not (f_h > 0 and f_l > 0):
        raise ValueError(f"frequencies must be positive; got f_h={f_h}, f_l={f_l}")
    difference = np.asarray(dtype(f_l / f_h) * np.asarray(absolute_high, dtype=dtype) - np.asarray(wrapped_low, dtype))
    np.subtract(dtype(np.pi), difference, out=difference)
    return dtype(np.pi) - _positive_remainder(difference, dtype(2.0 * np.pi))


def _positive_remainder(x: np.ndarray, period) -> np.ndarray:
    """``np.mod(x, period)`` for ``period > 0``, in place of ``x``, bit for bit but for the sign of a zero remainder:
    numpy's float remainder is ``fmod`` with ``period`` added to a negative remainder (its ``npy_divmod``), and
    ``fmod`` alone is about twice as fast."""
    np.fmod(x, period, out=x)
    np.add(x, period, out=x, where=x < 0)
    return x


def quantization_residual_noise(noise_high: np.ndarray | None, noise_low: np.ndarray | None, f_h: float,
                                f_l: float) -> np.ndarray | None:
    """``s_q = sqrt((f_l / f_h)^2 sigma_q,h^2 + sigma_q,l^2)`` (H, W) float32, radians: the standard deviation of
    ``eps`` that the images' rounding alone leaves (module docstring); None when either sequence has no floor.

    Parameters
    ----------
    noise_high, noise_low : ndarray (H, W) or None
        :func:`dptpu.fpp.fringe_noise.quantization_phase_noise` of the two frequencies' sequences.
    f_h, f_l : float
        Periods across the projector (> 0).
    """
    if noise_high is None or noise_low is None:
        return None
    ratio = f_l / f_h
    return np.hypot(ratio * np.asarray(noise_high, np.float64), np.asarray(noise_low, np.float64)).astype(np.float32)


def integer_frames_floor(modulation_high: np.ndarray, modulation_low: np.ndarray, steps_high: int, steps_low: int,
                         f_h: float, f_l: float) -> np.ndarray | None:
    """:func:`quantization_residual_noise` (H, W) float32 of two phase maps computed from integer frames (a camera's
    ``mono8`` / ``mono16``; the unwrap node's PhaseMaps): each map's
    :func:`dptpu.fpp.fringe_noise.quantization_phase_noise` from its modulation ``B`` (H, W) and step count ``N``.
    """
    return quantization_residual_noise(quantization_phase_noise(modulation_high, steps_high, np.uint16),
                                       quantization_phase_noise(modulation_low, steps_low, np.uint16), f_h, f_l)


def frequency_consistency(absolute_high: np.ndarray, wrapped_low: np.ndarray, f_h: float, f_l: float,
                          valid: np.ndarray, *, scale: float = DEFAULT_CONSISTENCY_SCALE,
                          floor: np.ndarray | None = None) -> np.ndarray:
    """Confidence ``(H, W)`` float32 in [0, 1] of each valid pixel's phase from the two frequencies' agreement.

    ``clip(1 - |eps| / (scale s), 0, 1)``, ``s`` = 1.4826 times the median ``|eps|`` of the valid pixels (module
    docstring, never below :data:`MIN_SIGMA_RAD`), per pixel never below ``floor`` (H, W) where given
    (:func:`quantization_residual_noise`); 0 where not ``valid``. Parameters as :func:`consistency_residual`'s;
    ``valid`` (H, W) bool.
    """
    if not scale > 0:
        raise ValueError(f"scale must be > 0; got {scale}")
    eps = consistency_residual(absolute_high, wrapped_low, f_h, f_l)
    np.abs(eps, out=eps)
    valid = np.asarray(valid, dtype=bool) & np.isfinite(eps)
    if not valid.any():
        return np.zeros(eps.shape, np.float32)
    sigma = max(MAD_TO_SIGMA * float(bracketed_median(eps[valid])), MIN_SIGMA_RAD)
    if floor is None:
        eps /= scale * sigma
    else:  # an infinite floor (no modulation) would pass anything: such pixels keep the scan's s
        pixel_sigma = np.asarray(floor).astype(np.float64)
        np.copyto(pixel_sigma, 0.0, where=~np.isfinite(pixel_sigma))
        np.maximum(pixel_sigma, sigma, out=pixel_sigma)
        pixel_sigma *= scale
        with np.errstate(invalid="ignore"):
            eps /= pixel_sigma
    # 1 - z / Z clipped to [0, 1], in place (NaN where not valid: set to 0 below)
    np.subtract(1.0, eps, out=eps)
    np.maximum(eps, 0.0, out=eps)
    np.minimum(eps, 1.0, out=eps)
    np.copyto(eps, 0.0, where=~valid)
    return eps.astype(np.float32)
