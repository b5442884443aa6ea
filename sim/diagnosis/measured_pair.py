"""Measured data as the DP-TPU network takes it: one two-frequency pair, the classical order and a reference order.

The network (docs/network.md) reads, per pixel, the wrapped phase of a high frequency ``f_h``, the wrapped phase
of a low frequency ``f_l`` and the classical method's fringe order of ``f_h``; it returns the order. A
:class:`MeasuredPair` holds those inputs built from measured data (:mod:`.cfpe_inputs`, :mod:`.sphere_inputs`),
the reference order from a higher-step measurement of the same scene, and a record of which parts are real and
which are synthesized (``provenance``), so that every figure computed on it can say so.

Convention: fringes along projector x; ``phi = 2 pi f x_p / W``; wrapped phases in ``[0, 2 pi)``; the reference
order is the order that makes the INPUT high phase absolute, ``Round((Phi_ref - psi_h) / 2 pi)`` (the label
convention of the twin's training samples, :mod:`dptpu.sim.dataset_samples`), so an input whose noise moves
``psi_h`` across a wrap is scored against the order that is right for it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dptpu.fpp import tpu

__all__ = ["MeasuredPair", "reference_order", "order_accuracy", "mf_coarse_order"]

_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True, eq=False)  # holds arrays
class MeasuredPair:
    """Network inputs built from measured data, and the reference to score them against.

    Attributes
    ----------
    name : str
        Short label, e.g. ``cfpe06`` or ``sphere_1sigma``.
    wrapped_high, wrapped_low : ndarray (H, W) float64
        Wrapped phases in radians, ``[0, 2 pi)``; 0 where not ``valid``.
    coarse_order : ndarray (H, W) int32
        The classical ``method``'s order of ``f_h`` from the two phases (Eq. (5) for MF).
    reference_order : ndarray (H, W) int32
        Order of ``f_h`` from the reference measurement (:func:`reference_order`).
    reference_phase : ndarray (H, W) float64
        The reference absolute phase of ``f_h`` (radians), NaN where not ``valid``.
    valid : ndarray (H, W) bool
        Pixels that count.
    frequency_high, frequency_low : float
        Periods across the projector width ``extent_px`` (the low one in the network's convention, e.g. 1 for
        MF).
    method : str
        The classical method of ``coarse_order`` (``mf``).
    extent_px : int
        Projector width along the fringe axis, pixels.
    provenance : dict
        What is real and what is synthesized (strings), written into ``downstream.json``.
    """

    name: str
    wrapped_high: np.ndarray
    wrapped_low: np.ndarray
    coarse_order: np.ndarray
    reference_order: np.ndarray
    reference_phase: np.ndarray
    valid: np.ndarray
    frequency_high: float
    frequency_low: float
    method: str
    extent_px: int
    provenance: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return self.valid.shape

    def absolute_phase(self, order) -> np.ndarray:
        """``psi_h + 2 pi k`` (Eq. (3)) for an order map ``(H, W)``; NaN where not ``valid``."""
        return np.where(self.valid, self.wrapped_high + _TWO_PI * np.asarray(order), np.nan)

    def projector_x(self, order) -> np.ndarray:
        """Projector coordinate ``x_p = phi W / (2 pi f_h)`` (H, W) of an order map, NaN where not ``valid``."""
        return self.absolute_phase(order) * self.extent_px / (_TWO_PI * self.frequency_high)


def reference_order(reference_phase, wrapped_high) -> np.ndarray:
    """``Round((Phi_ref - psi_h) / 2 pi)`` (H, W) int32; 0 where either input is not finite.

    Parameters
    ----------
    reference_phase : ndarray (H, W)
        Absolute phase of ``f_h`` from the reference measurement, radians.
    wrapped_high : ndarray (H, W)
        The input's wrapped phase of ``f_h``, radians, ``[0, 2 pi)``.
    """
    reference_phase = np.asarray(reference_phase, dtype=np.float64)
    wrapped_high = np.asarray(wrapped_high, dtype=np.float64)
    if reference_phase.shape != wrapped_high.shape or reference_phase.ndim != 2:
        raise ValueError(f"reference_phase and wrapped_high must share a shape (H, W); got {reference_phase.shape} "
                         f"and {wrapped_high.shape}")
    with np.errstate(invalid="ignore"):
        order = np.rint((reference_phase - wrapped_high) / _TWO_PI)
    return np.where(np.isfinite(order), order, 0).astype(np.int32)


def mf_coarse_order(wrapped_high, wrapped_low, frequency_high, valid) -> np.ndarray:
    """Classical MF order of ``f_h`` from a low phase of ``f_l = 1`` (Eq. (5)), (H, W) int32, 0 off ``valid``."""
    result = tpu.unwrap_mf(np.where(valid, wrapped_high, np.nan), np.where(valid, wrapped_low, np.nan),
                           float(frequency_high), 1.0, valid=valid)
    return np.where(valid, result.fringe_order, 0).astype(np.int32)


def order_accuracy(order, pair: MeasuredPair) -> float:
    """Fraction of ``pair.valid`` pixels whose ``order`` equals the reference order, in ``[0, 1]``."""
    order = np.asarray(order)
    if order.shape != pair.shape:
        raise ValueError(f"order must have the pair's shape {pair.shape}; got {order.shape}")
    count = int(pair.valid.sum())
    if count == 0:
        raise ValueError(f"{pair.name}: no valid pixels to score")
    return float(np.count_nonzero((order == pair.reference_order) & pair.valid) / count)
