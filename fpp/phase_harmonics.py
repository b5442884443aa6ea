"""The N-step phase's harmonic error from a nonlinear projector response: fitted against a reference, then removed.

Eq. (2) recovers the phase exactly from a pure sinusoid. A projector whose output is not linear in its input (a
gamma, a saturating lamp) projects a fringe with harmonics: ``I = A + sum_k B_k cos(k (psi + delta_n))``. The
least-squares sums of an N-step sequence cancel every harmonic ``k`` but those with ``k = 1 (mod N)`` or ``k = -1
(mod N)``; the first two left, ``k = N - 1`` and ``k = N + 1``, alias onto the fundamental and turn into a phase
error that repeats N times per fringe period:

    psi_measured = psi + a cos(N psi) + b sin(N psi)        (to first order in B_{N -+ 1} / B_1)

For the paper's 3 steps that is the projector's second harmonic, its gamma: 0.16 rad on the real CFPE captures
(``docs/cloud-eval.md``), enough to put the low beats of a three-period heterodyne whole beat periods off. Twelve
steps cancel harmonics up to the 10th, so a 12-step phase of the same scene is the reference that calibrates
``(a, b)`` (:func:`fit_harmonic_phase_error`), a property of the projector and its pattern levels, not of the
scene; :func:`remove_harmonic_phase_error` then inverts the model on any later N-step phase of that projector.

:class:`ProjectorPhaseResponse` holds one such error per step count: the rig calibration ``projector.phase_response``
(``dptpu calibrate response``, docs/calibration.md) that every phase computation of the rig applies
(:meth:`ProjectorPhaseResponse.correct`). The error is a function of the pattern's phase ``psi + phase_offset`` (the
projected level), whatever the step direction: with the sequence's ``phase_offset`` the model holds for any offset.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np

__all__ = ["HarmonicPhaseError", "ProjectorPhaseResponse", "fit_harmonic_phase_error", "remove_harmonic_phase_error"]

_TWO_PI = 2.0 * np.pi
#: Newton steps of the inversion (quadratic convergence from ``psi_measured - error(psi_measured)``; the model is
#: invertible while ``N |(a, b)| < 1``: 0.5 for the CFPE projector at N = 3).
_INVERSION_STEPS = 4
#: Samples over one period of the tabulated inverse (:meth:`ProjectorPhaseResponse.correct`): linear interpolation
#: of a correction of amplitude ``a`` at ``N`` per period errs by at most ``(2 pi / S)^2 N^2 a / 8``: 1e-6 rad for
#: the CFPE projector (a = 0.17, N = 3).
_TABLE_SAMPLES = 4096
#: cv2.remap takes maps of fewer than 32767 rows and columns.
_REMAP_MAX_SIDE = 32767


@dataclass(frozen=True)
class HarmonicPhaseError:
    """``psi_measured - psi = cos_rad cos(N psi) + sin_rad sin(N psi) + sum_j (c_j cos(j N psi) + s_j sin(j N psi))``
    of an N-step phase (``N = steps``; ``j = 2, 3, ...`` over ``higher_cos_rad``, ``higher_sin_rad``).

    The first term is the model of the module docstring; the higher multiples ``2N, 3N`` carry its second- and
    third-order terms (the fundamental's error squared, the harmonics ``2N -+ 1``): a gamma of 2.2 leaves 0.035 rad
    of a 0.26 rad 3-step error with the first term alone, 0.008 rad with three (tests/fpp/test_phase_response.py).
    """

    steps: int
    cos_rad: float
    sin_rad: float
    higher_cos_rad: tuple[float, ...] = ()
    higher_sin_rad: tuple[float, ...] = ()

    def __post_init__(self):
        if len(self.higher_cos_rad) != len(self.higher_sin_rad):
            raise ValueError(f"higher_cos_rad and higher_sin_rad must be of one length; got "
                             f"{len(self.higher_cos_rad)} and {len(self.higher_sin_rad)}")

    @property
    def terms(self) -> tuple[tuple[int, float, float], ...]:
        """``(multiple m, cos, sin)`` of each term ``cos cos(m psi) + sin sin(m psi)``, ``m = N, 2N, ...``."""
        first = ((self.steps, float(self.cos_rad), float(self.sin_rad)),)
        return first + tuple((j * self.steps, float(c), float(s))
                             for j, (c, s) in enumerate(zip(self.higher_cos_rad, self.higher_sin_rad), start=2))

    @property
    def amplitude_rad(self) -> float:
        """Peak phase error of the first term (at ``N psi``), radians."""
        return float(np.hypot(self.cos_rad, self.sin_rad))

    @property
    def min_slope(self) -> float:
        """``min d error / d psi`` over a period (sampled 64 times per period of the highest term): the model
        ``psi -> psi + error(psi)`` is invertible (increasing) while it is above -1 (one term: ``N |(a, b)| < 1``)."""
        highest = self.terms[-1][0]
        grid = np.linspace(0.0, _TWO_PI, 64 * highest, endpoint=False)
        return float(np.min(self.slope(grid)))

    def at(self, psi: np.ndarray) -> np.ndarray:
        """The error at the true phase ``psi`` (radians)."""
        return sum(c * np.cos(m * psi) + s * np.sin(m * psi) for m, c, s in self.terms)

    def slope(self, psi: np.ndarray) -> np.ndarray:
        """d error / d psi at the true phase ``psi``."""
        return sum(m * (s * np.cos(m * psi) - c * np.sin(m * psi)) for m, c, s in self.terms)


def fit_harmonic_phase_error(measured, reference, valid, steps: int, *, multiples: int = 1) -> HarmonicPhaseError:
    """Least-squares ``(a, b)`` of the module docstring's model from pairs of phase maps of the same scenes.

    Parameters
    ----------
    measured : sequence of ndarray (H, W)
        Wrapped phases of ``steps``-step sequences, radians.
    reference : sequence of ndarray (H, W)
        Wrapped phases of the same frequencies without the harmonic error (e.g. 12-step sequences), radians.
    valid : sequence of ndarray (H, W) bool
        Pixels where both are good, one mask per pair.
    steps : int
        N of the measured sequences (>= 3).
    multiples : int
        Terms fitted, at ``N, 2N, ..., multiples x N`` times the phase (:class:`HarmonicPhaseError`); 1: the
        first-order model alone.
    """
    if steps < 3:
        raise ValueError(f"steps must be >= 3 (the N of an N-step phase); got {steps}")
    if multiples < 1:
        raise ValueError(f"multiples must be >= 1; got {multiples}")
    rows, errors = [], []
    for psi, ref, mask in zip(measured, reference, valid, strict=True):
        psi, ref, mask = np.asarray(psi, np.float64), np.asarray(ref, np.float64), np.asarray(mask, bool)
        if psi.shape != ref.shape or psi.shape != mask.shape:
            raise ValueError(f"measured, reference and valid must be of one shape; got {psi.shape}, {ref.shape}, "
                             f"{mask.shape}")
        truth = ref[mask]
        columns = []
        for j in range(1, multiples + 1):
            columns += [np.cos(j * steps * truth), np.sin(j * steps * truth)]
        rows.append(np.stack(columns, axis=1))  # (P, 2 multiples)
        errors.append(np.angle(np.exp(1j * (psi[mask] - truth))))  # (P,) wrapped to (-pi, pi]
    design = np.concatenate(rows) if rows else np.zeros((0, 2 * multiples))
    if design.shape[0] < 2 * multiples:
        raise ValueError("no valid pixel to fit the harmonic phase error on")
    coefficients, *_ = np.linalg.lstsq(design, np.concatenate(errors), rcond=None)
    return HarmonicPhaseError(steps=int(steps), cos_rad=float(coefficients[0]), sin_rad=float(coefficients[1]),
                              higher_cos_rad=tuple(float(c) for c in coefficients[2::2]),
                              higher_sin_rad=tuple(float(c) for c in coefficients[3::2]))


def remove_harmonic_phase_error(psi, error: HarmonicPhaseError) -> np.ndarray:
    """The phase without ``error``: ``psi_true`` solving ``psi_measured = psi_true + error.at(psi_true)`` by Newton's
    method from ``psi_measured - error.at(psi_measured)``, wrapped to ``[0, 2 pi)``; NaN stays NaN."""
    if not error.min_slope > -1.0:
        raise ValueError(f"a harmonic phase error of {error.amplitude_rad:.3g} rad at {error.steps} steps cannot be "
                         f"inverted (needs its slope above -1, steps x amplitude < 1 for one term; got "
                         f"{error.min_slope:.3g})")
    measured = np.asarray(psi, dtype=np.float64)
    true = measured - error.at(measured)
    for _ in range(_INVERSION_STEPS):
        true = true - (true + error.at(true) - measured) / (1.0 + error.slope(true))
    return np.mod(true, _TWO_PI)


@dataclass(frozen=True)
class ProjectorPhaseResponse:
    """A projector's harmonic phase error per step count: the rig file's ``projector.phase_response``.

    Attributes
    ----------
    errors : mapping int -> HarmonicPhaseError
        ``N -> (a, b)`` of :class:`HarmonicPhaseError`, in the pattern's phase (module docstring). Step counts
        absent from it are left as they are (12 steps and more carry no error of the projector's first
        harmonics).
    """

    errors: Mapping[int, HarmonicPhaseError] = field(default_factory=dict)

    def __post_init__(self):
        for steps, error in self.errors.items():
            if error.steps != steps:
                raise ValueError(f"the phase response of {steps} steps holds an error of {error.steps} steps")
            if not error.min_slope > -1.0:
                raise ValueError(f"a harmonic phase error of {error.amplitude_rad:.3g} rad at {steps} steps cannot "
                                 f"be inverted (needs its slope above -1; got {error.min_slope:.3g})")

    @property
    def steps(self) -> tuple[int, ...]:
        """The step counts it corrects, ascending."""
        return tuple(sorted(self.errors))

    def for_steps(self, steps: int) -> HarmonicPhaseError | None:
        """The error of ``steps``-step phases, or None when the response holds none."""
        return self.errors.get(int(steps))

    @cached_property
    def _corrections(self) -> dict[int, np.ndarray]:
        """Per step count, ``measured - true`` at ``_TABLE_SAMPLES`` measured phases over one period (the inverse
        of the model by :func:`remove_harmonic_phase_error`, tabulated once)."""
        grid = np.linspace(0.0, _TWO_PI, _TABLE_SAMPLES, endpoint=False)
        tables = {}
        for steps, error in self.errors.items():
            true = remove_harmonic_phase_error(grid, error)
            tables[steps] = np.angle(np.exp(1j * (grid - true)))  # (S,) small, periodic
        return tables

    def correct(self, psi, steps: int, *, phase_offset: float = 0.0) -> np.ndarray:
        """The wrapped phase of an N-step sequence without the projector's harmonic error.

        Parameters
        ----------
        psi : ndarray
            Wrapped phase in ``[0, 2 pi)`` (any shape; NaN stays NaN), as :func:`dptpu.fpp.phase.wrapped_phase`
            gives it for the sequence's ``phase_offset``.
        steps : int
            N of the sequence.
        phase_offset : float
            The sequence's ``phase_offset`` (radians): the error is periodic in ``psi + phase_offset``.

        Returns
        -------
        ndarray
            ``psi`` itself (the same object) when the response holds no error for ``steps``; else the corrected
            phase in ``[0, 2 pi)``, of ``psi``'s float dtype: ``psi - c(psi + phase_offset)`` with ``c`` the model
            inverted by Newton's method on a table of one period, interpolated linearly (one ``cv2.remap``).
        """
        if int(steps) not in self.errors:
            return psi
        psi = np.asarray(psi)
        dtype = psi.dtype if np.issubdtype(psi.dtype, np.floating) else np.dtype(np.float64)
        period = dtype.type(_TWO_PI)
        pattern_phase = psi
        if phase_offset:
            pattern_phase = psi + dtype.type(float(phase_offset) % _TWO_PI)  # in [0, 4 pi)
            pattern_phase = np.where(pattern_phase >= period, pattern_phase - period, pattern_phase)
        correction = _periodic_lookup(self._corrections[int(steps)], pattern_phase).astype(dtype, copy=False)
        # |correction| < 1 rad: back into [0, 2 pi) by one period either way (np.mod takes 50 ms on float32
        # 640x480, two np.where 1 ms); NaN compares False and stays NaN
        corrected = psi - correction
        corrected = np.where(corrected < 0, corrected + period, corrected)
        return np.where(corrected >= period, corrected - period, corrected)


def _periodic_lookup(table: np.ndarray, phase) -> np.ndarray:
    """``table`` (S,) of one period sampled at ``2 pi s / S``, interpolated linearly at ``phase`` (any shape): one
    ``cv2.remap`` with a wrapping border for an image (3 ms at 640x480 where ``np.interp`` takes 130), else
    ``np.interp``."""
    phase = np.asarray(phase)
    samples = table.shape[0]
    if phase.ndim == 2 and 0 < phase.shape[0] < _REMAP_MAX_SIDE and 0 < phase.shape[1] < _REMAP_MAX_SIDE:
        columns = (phase * (samples / _TWO_PI)).astype(np.float32)  # (H, W) table index
        return cv2.remap(table.astype(np.float32)[None, :], columns, np.zeros_like(columns), cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_WRAP)
    grid = np.linspace(0.0, _TWO_PI, samples, endpoint=False)
    return np.interp(phase, grid, table, period=_TWO_PI)
