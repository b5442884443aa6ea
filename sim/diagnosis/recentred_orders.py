"""Fringe orders of a capture whose phases share a bias: MF (Eq. (5)) with the rounding margin centred again.

A step-scale error or a drift biases every sequence's phase by about the same constant ``b`` (the mean of the
step errors, a few hundredths of a radian). MF rounds ``q = (r psi_l - psi_h) / (2 pi)`` (``r = f_h / f_l``),
which ``b`` moves by ``(r - 1) b / (2 pi)``: with ``r = 96`` a bias of 0.029 rad (a 1 % step-scale error at 12
steps) is 0.44 of an order, so the noise rounds whole regions one order off, the registered pose follows them
and a smooth effect (lens distortion, blur) explains the wreck better than the step error does. The bias is the
same on every pixel, so it shows as the circular mean ``c`` of ``2 pi (q - round(q))``; orders rounded from
``q - c / (2 pi)`` are right wherever the phase noise is within the margin again. (A ``c`` off by a whole
``2 pi / (r - 1)`` in ``b`` only moves every order by one: a pose ambiguity the registration's wrapped
refinement and the per-sequence phase offsets absorb.)
"""
from __future__ import annotations

import numpy as np

from dptpu.fpp.phase import wrapped_phase

from .measured import Measured

__all__ = ["mf_bias_rad", "recentred_absolute_phase"]


def _wrapped(measured: Measured, index: int) -> np.ndarray:
    sequence = measured.sequences[index]
    return wrapped_phase(measured.frames[index], shift_sign=sequence.shift_sign,
                         phase_offset=sequence.phase_offset).phase


def mf_bias_rad(q: np.ndarray) -> float:
    """Circular mean (radians, in (-pi, pi]) of ``2 pi (q - round(q))`` over the finite values of ``q``."""
    angle = 2.0 * np.pi * q[np.isfinite(q)]
    return float(np.arctan2(np.mean(np.sin(angle)), np.mean(np.cos(angle)))) if angle.size else 0.0


def recentred_absolute_phase(measured: Measured, valid: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The absolute phase (H, W) of the highest frequency from MF orders rounded about the data's own centre,
    and that centre (radians of ``2 pi q``); None unless the capture holds frames of two sequences, the lowest
    of frequency <= 1 (its wrapped phase is absolute)."""
    if not measured.has_frames or len(measured.sequences) != 2:
        return None
    frequencies = [s.frequency for s in measured.sequences]
    high, low = int(np.argmax(frequencies)), int(np.argmin(frequencies))
    if high == low or frequencies[low] > 1.0:
        return None
    psi_h, psi_l = _wrapped(measured, high), _wrapped(measured, low)
    ratio = frequencies[high] / frequencies[low]
    q = np.where(valid, (ratio * psi_l - psi_h) / (2.0 * np.pi), np.nan)
    centre = mf_bias_rad(q)
    order = np.round(q - centre / (2.0 * np.pi))
    return np.where(valid, psi_h + 2.0 * np.pi * order, np.nan), centre
