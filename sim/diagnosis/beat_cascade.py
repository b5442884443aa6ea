"""The three-frequency heterodyne tree as a cascade of two MF pairs, one per level, for a solver at each level.

Three wrapped phases ``psi_0, psi_1, psi_2`` of ``f_0 > f_1 > f_2`` (CFPE: periods 42, 45, 48 px over 1920 px)
beat into ``beat_12 = psi_0 - psi_1`` of ``f_12 = f_0 - f_1`` and the beat of beats ``beat_123 = beat_12 -
(psi_1 - psi_2)`` of ``f_123 = f_12 - (f_1 - f_2) <= 1``, which is absolute (Eq. (6)). The heterodyne then walks
down with the rounding of Eq. (5) twice. Each step is an MF pair (a wrapped high phase, an absolute low phase of
``f_l = 1`` in some projector width) and can be solved by any MF solver, the classical rounding or the network:

- **level 1, the beat level** (:func:`beat_level_phases`): high ``beat_12``, low ``beat_123``; in the width
  ``W / f_123`` (5040 px for CFPE) the low phase is ``f_l = 1`` and the high one ``f_h = f_12 / f_123`` (8).
  The real projector covers only ``f_123`` of that width (0.381), so the low phase is shifted by ``m`` high
  periods (``m = round(f_h (1 - f_123) / 2)``, 2 for CFPE) to put the projector in the middle of it, away from
  the ends where a noisy low phase wraps: the high phase is unchanged (``2 pi m``) and the order is ``k_12 + m``.
- **level 2, the top level** (:func:`top_level_low`): high ``psi_0`` (``f_h = f_0``), low the absolute beat
  ``beat_12 + 2 pi k_12`` rescaled by ``1 / f_12`` to ``f_l = 1`` over the projector's width.

With the classical rounding at both levels this IS the heterodyne (:func:`dptpu.fpp.tpu.unwrap_heterodyne`; it
differs only where the beat of beats' noise carries it below 0, which the heterodyne reads near ``2 pi``, or an
order off the projector's far end, which the wrapped low phase of level 2 folds back) and level 2 is the ``het12``
pair of :mod:`.cfpe_inputs` (the same order on all but the pixels whose beat of beats wraps at the shifted ends).
Its failures at level 1 (one ``k_12`` off: the top order moves by ``f_0 / f_12`` orders, 15 for CFPE) are beyond
what a solver at level 2 can see; a solver at level 1 sees them as one-order errors of an MF pair of ratio 8.
Noise and response errors: ``beat_12`` carries the sum of two phases' errors, ``beat_123`` four (``psi_0 - 2 psi_1
+ psi_2``), each at its own phase.

Used by the measured pairs (:func:`.cfpe_inputs.cfpe_cascade`) and the twin's training samples
(:mod:`.twin_pairs`) alike, so both are built by the same code.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .measured_pair import MeasuredPair, mf_coarse_order, reference_order

__all__ = ["beat_frequencies", "BeatLevel", "beat_level_phases", "top_level_low", "CascadePair", "cascade_pair"]

_TWO_PI = 2.0 * np.pi


def beat_frequencies(frequencies) -> tuple[float, float]:
    """``(f_12, f_123)`` of three frequencies ``f_0 > f_1 > f_2``: the beats of the heterodyne tree (Eq. (6))."""
    f0, f1, f2 = (float(f) for f in frequencies)
    f_12 = f0 - f1
    f_123 = f_12 - (f1 - f2)
    if not (f0 > f1 > f2 > 0 and f_12 > 1.0 and 0.0 < f_123 <= 1.0):
        raise ValueError(f"frequencies must be three decreasing values whose beat of beats lies in (0, 1]; got "
                         f"{[f0, f1, f2]} (f_12 = {f_12:g}, f_123 = {f_123:g})")
    return f_12, f_123


@dataclass(frozen=True, eq=False)  # holds arrays
class BeatLevel:
    """Level 1 of the cascade as an MF pair.

    Attributes
    ----------
    wrapped_high : ndarray (H, W)
        ``beat_12`` in ``[0, 2 pi)``.
    wrapped_low : ndarray (H, W)
        ``beat_123`` shifted by ``2 pi offset / frequency_high``, in ``[0, 2 pi)``.
    frequency_high : float
        ``f_12 / f_123`` (the low one is 1).
    offset : int
        ``m``: the pair's order is ``k_12 + m``.
    f_12 : float
        The beat's frequency over the projector.
    extent_px : int
        The width in which the low phase is ``f_l = 1``: ``W / f_123`` (rounded).
    """

    wrapped_high: np.ndarray
    wrapped_low: np.ndarray
    frequency_high: float
    offset: int
    f_12: float
    extent_px: int


def beat_level_phases(psi, frequencies, projector_width_px: int) -> BeatLevel:
    """Level 1 of the cascade from the wrapped phases ``psi`` (3 arrays, radians, highest frequency first).

    ``beat_123`` spans ``[0, 2 pi f_123)`` over the projector; a value in the gap above it is noise below 0 and is
    read as negative (as :func:`.cfpe_inputs.low_phase` reads it) before the shift.
    """
    f_12, f_123 = beat_frequencies(frequencies)
    beat_12 = np.mod(psi[0] - psi[1], _TWO_PI)  # phase of f_12, Eq. (6)
    beat = np.mod(beat_12 - np.mod(psi[1] - psi[2], _TWO_PI), _TWO_PI)  # phase of f_123, [0, 2pi)
    beat = np.where(beat > np.pi * (1.0 + f_123), beat - _TWO_PI, beat)
    f_h = f_12 / f_123
    offset = int(round(f_h * (1.0 - f_123) / 2.0))
    return BeatLevel(wrapped_high=beat_12, wrapped_low=np.mod(beat + _TWO_PI * offset / f_h, _TWO_PI),
                     frequency_high=f_h, offset=offset, f_12=f_12,
                     extent_px=int(round(projector_width_px / f_123)))


def top_level_low(beat_12, beat_order, f_12: float) -> np.ndarray:
    """Level 2's low phase: the absolute beat ``beat_12 + 2 pi k_12`` rescaled to ``f_l = 1`` (Eq. (3)), wrapped."""
    return np.mod((np.asarray(beat_12) + _TWO_PI * np.asarray(beat_order)) / f_12, _TWO_PI)


@dataclass(frozen=True, eq=False)  # holds arrays
class CascadePair:
    """A three-frequency measurement as the cascade's two MF pairs, with the reference at both levels.

    Attributes
    ----------
    beat : MeasuredPair
        Level 1 (:func:`beat_level_phases`): its orders are ``k_12 + offset``; ``coarse_order`` the classical one.
    top : MeasuredPair
        Level 2 with the classical level-1 order (the heterodyne's pair: its ``coarse_order`` is the heterodyne
        order of ``f_0``).
    offset : int
        Level 1's order shift ``m``.
    f_12 : float
    """

    beat: MeasuredPair
    top: MeasuredPair
    offset: int
    f_12: float

    def top_pair(self, beat_order) -> MeasuredPair:
        """Level 2 with the low phase from a level-1 order map (level 1's convention, ``k_12 + offset``): the
        wrapped low phase and the classical MF order of ``f_0`` recomputed, the reference unchanged."""
        valid = self.top.valid
        low = np.where(valid, top_level_low(self.beat.wrapped_high, np.asarray(beat_order) - self.offset,
                                            self.f_12), 0.0)
        return dataclasses.replace(self.top, wrapped_low=low,
                                   coarse_order=mf_coarse_order(self.top.wrapped_high, low,
                                                                self.top.frequency_high, valid))


def cascade_pair(name: str, psi3, mask3, reference_phase, frequencies, *, extent_px: int,
                 provenance: dict | None = None) -> CascadePair:
    """Both levels of the cascade from 3-step (or any) phases of three frequencies and a reference absolute phase
    of the highest (NaN where unknown); valid where ``mask3`` holds and the reference lies on the projector."""
    f_0 = float(frequencies[0])
    reference_phase = np.asarray(reference_phase, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        on_projector = (reference_phase >= 0) & (reference_phase < _TWO_PI * f_0)
    valid = np.asarray(mask3, bool) & on_projector
    level = beat_level_phases(psi3, frequencies, extent_px)
    phi_ref = np.where(valid, reference_phase, np.nan)
    beat_h = np.where(valid, level.wrapped_high, 0.0)
    beat_l = np.where(valid, level.wrapped_low, 0.0)
    beat_ref = phi_ref * level.f_12 / f_0 + _TWO_PI * level.offset  # Phi_12 = Phi_0 f_12 / f_0, shifted
    provenance = dict(provenance or {})
    beat = MeasuredPair(name=f"{name}/beat", wrapped_high=beat_h, wrapped_low=beat_l,
                        coarse_order=mf_coarse_order(beat_h, beat_l, level.frequency_high, valid),
                        reference_order=reference_order(beat_ref, beat_h), reference_phase=beat_ref, valid=valid,
                        frequency_high=level.frequency_high, frequency_low=1.0, method="mf",
                        extent_px=level.extent_px, provenance=provenance)
    psi_h = np.where(valid, psi3[0], 0.0)
    psi_l = np.where(valid, top_level_low(level.wrapped_high, beat.coarse_order - level.offset, level.f_12), 0.0)
    top = MeasuredPair(name=name, wrapped_high=psi_h, wrapped_low=psi_l,
                       coarse_order=mf_coarse_order(psi_h, psi_l, f_0, valid),
                       reference_order=reference_order(phi_ref, psi_h), reference_phase=phi_ref, valid=valid,
                       frequency_high=f_0, frequency_low=1.0, method="mf", extent_px=int(extent_px),
                       provenance=provenance)
    return CascadePair(beat=beat, top=top, offset=level.offset, f_12=level.f_12)
