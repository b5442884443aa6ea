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
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HarmonicPhaseError", "fit_harmonic_phase_error", "remove_harmonic_phase_error"]

_TWO_PI = 2.0 * np.pi
#: Newton steps of the inversion (quadratic convergence from ``psi_measured - error(psi_measured)``; the model is
#: invertible while ``N |(a, b)| < 1``: 0.5 for the CFPE projector at N = 3).
_INVERSION_STEPS = 4


@dataclass(frozen=True)
class HarmonicPhaseError:
    """``psi_measured - psi = cos_rad * cos(steps psi) + sin_rad * sin(steps psi)`` of an N-step phase."""

    steps: int
    cos_rad: float
    sin_rad: float

    @property
    def amplitude_rad(self) -> float:
        """Peak phase error, radians."""
        return float(np.hypot(self.cos_rad, self.sin_rad))

    def at(self, psi: np.ndarray) -> np.ndarray:
        """The error at the true phase ``psi`` (radians)."""
        return self.cos_rad * np.cos(self.steps * psi) + self.sin_rad * np.sin(self.steps * psi)

    def slope(self, psi: np.ndarray) -> np.ndarray:
        """d error / d psi at the true phase ``psi``."""
        return self.steps * (self.sin_rad * np.cos(self.steps * psi) - self.cos_rad * np.sin(self.steps * psi))


def fit_harmonic_phase_error(measured, reference, valid, steps: int) -> HarmonicPhaseError:
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
    """
    if steps < 3:
        raise ValueError(f"steps must be >= 3 (the N of an N-step phase); got {steps}")
    rows, errors = [], []
    for psi, ref, mask in zip(measured, reference, valid, strict=True):
        psi, ref, mask = np.asarray(psi, np.float64), np.asarray(ref, np.float64), np.asarray(mask, bool)
        if psi.shape != ref.shape or psi.shape != mask.shape:
            raise ValueError(f"measured, reference and valid must be of one shape; got {psi.shape}, {ref.shape}, "
                             f"{mask.shape}")
        truth = ref[mask]
        rows.append(np.stack([np.cos(steps * truth), np.sin(steps * truth)], axis=1))  # (P, 2)
        errors.append(np.angle(np.exp(1j * (psi[mask] - truth))))  # (P,) wrapped to (-pi, pi]
    design = np.concatenate(rows) if rows else np.zeros((0, 2))
    if design.shape[0] < 2:
        raise ValueError("no valid pixel to fit the harmonic phase error on")
    (a, b), *_ = np.linalg.lstsq(design, np.concatenate(errors), rcond=None)
    return HarmonicPhaseError(steps=int(steps), cos_rad=float(a), sin_rad=float(b))


def remove_harmonic_phase_error(psi, error: HarmonicPhaseError) -> np.ndarray:
    """The phase without ``error``: ``psi_true`` solving ``psi_measured = psi_true + error.at(psi_true)`` by Newton's
    method from ``psi_measured - error.at(psi_measured)``, wrapped to ``[0, 2 pi)``; NaN stays NaN."""
    if not error.steps * error.amplitude_rad < 1.0:
        raise ValueError(f"a harmonic phase error of {error.amplitude_rad:.3g} rad at {error.steps} steps cannot be "
                         f"inverted (needs steps x amplitude < 1)")
    measured = np.asarray(psi, dtype=np.float64)
    true = measured - error.at(measured)
    for _ in range(_INVERSION_STEPS):
        true = true - (true + error.at(true) - measured) / (1.0 + error.slope(true))
    return np.mod(true, _TWO_PI)
