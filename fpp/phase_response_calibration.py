"""The projector's phase response calibrated from captures: N-step phases fitted against 12-step phases of the same
scene (``dptpu calibrate response``, docs/calibration.md).

A capture calibrates the response when it holds a phase sequence of :data:`REFERENCE_MIN_STEPS` steps or more (the
reference: it cancels the projector's harmonics up to the 10th, :mod:`dptpu.fpp.phase_harmonics`) and, of the same
frequency, the N-step phases to calibrate:

- **explicit**: another phase sequence of the same frequency with fewer steps (a 3-step sequence captured beside the
  12-step one);
- **taken from the reference**: every ``N`` dividing the reference's ``M`` steps with ``3 <= N <= M / 2``: frames
  ``0, M/N, 2 M/N, ...`` of an M-step sequence ARE an N-step sequence (shifts ``2 pi n / N``), the way the CFPE data
  gives its 3-step phases (steps 0, 4, 8 of 12). One 12-step capture calibrates 3, 4 and 6 steps.

Each N's error (the terms at ``N, 2N, 3N`` times the phase, :data:`DEFAULT_MULTIPLES`) is fitted over every pair
of every capture (:func:`dptpu.fpp.phase_harmonics.fit_harmonic_phase_error`) in the pattern's phase
``psi + phase_offset``, on the pixels both sequences' quality masks keep (:func:`dptpu.fpp.phase.quality_mask`).
The projector's defocus attenuates the harmonics of fine fringes more than the fundamental, so the error may shrink
with the frequency; the fit per frequency is reported beside the pooled one (:attr:`StepFit.
amplitude_by_frequency_rad`) so that a user sees whether one response serves them all.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from . import phase
from .capture import CAPTURE_FILE, Capture, PhaseSequence, load_sequence_images
from .frequencies import same_frequency
from .phase_harmonics import HarmonicPhaseError, ProjectorPhaseResponse, fit_harmonic_phase_error

__all__ = ["DEFAULT_MULTIPLES", "REFERENCE_MIN_STEPS", "PhaseResponseCalibration", "StepFit",
           "calibrate_phase_response"]

#: Fewest steps of a reference sequence: 12 steps cancel every harmonic below the 11th.
REFERENCE_MIN_STEPS = 12
#: Terms fitted per step count, at ``N, 2N, 3N`` times the phase (:class:`dptpu.fpp.phase_harmonics.
#: HarmonicPhaseError`): a gamma of 2.2 leaves 0.035 rad of its 3-step error with one, 0.008 rad with three.
DEFAULT_MULTIPLES = 3
#: Default ``min_modulation`` as a fraction of the camera's full scale (that of ``dptpu unwrap``).
_MIN_MODULATION_FRACTION = 0.02


@dataclass(frozen=True)
class StepFit:
    """The fit of one step count.

    Attributes
    ----------
    error : HarmonicPhaseError
        Pooled over every pair.
    pixels : int
        Pixel samples fitted (over all pairs).
    pairs : tuple of str
        What was fitted, e.g. ``"cap/capture.yaml: frequency 16, 3 of the 12 steps"``.
    rms_before_rad, rms_after_rad : float
        RMS of the N-step phase minus the reference, wrapped, before and after the correction
        (:meth:`dptpu.fpp.phase_harmonics.ProjectorPhaseResponse.correct`): what remains is noise.
    amplitude_by_frequency_rad : dict float -> float
        The amplitude fitted on each frequency alone.
    """

    error: HarmonicPhaseError
    pixels: int
    pairs: tuple[str, ...]
    rms_before_rad: float
    rms_after_rad: float
    amplitude_by_frequency_rad: dict


@dataclass(frozen=True)
class PhaseResponseCalibration:
    """``response`` (the rig file's ``projector.phase_response``) and the fit of each step count in it."""

    response: ProjectorPhaseResponse
    fits: dict  # int -> StepFit


@dataclass(frozen=True)
class _Pair:
    steps: int
    frequency: float
    measured: np.ndarray  # (H, W) N-step wrapped phase
    reference: np.ndarray  # (H, W) M-step wrapped phase of the same frequency
    valid: np.ndarray  # (H, W) bool
    phase_offset: float  # of the measured sequence
    label: str


def calibrate_phase_response(captures: Iterable[Capture], *, steps: Sequence[int] | None = None,
                             min_modulation: float | None = None,
                             multiples: int = DEFAULT_MULTIPLES,
                             progress: Callable[[str], None] | None = None) -> PhaseResponseCalibration:
    """Fit the projector's harmonic phase error per step count from captures (module docstring).

    Parameters
    ----------
    captures : iterable of Capture
        From :func:`dptpu.fpp.capture.read_capture`; of one projector (and its pattern levels).
    steps : sequence of int, optional
        The step counts to calibrate; default every one the captures provide.
    min_modulation : float, optional
        Smallest modulation ``B`` of a pixel fitted, camera digital numbers; default 2 % of full scale.
    multiples : int
        Terms of each step count's error, at ``N, 2N, ...`` times the phase.
    progress : callable, optional
        Called with the name of each step as it starts (a capture's phases, a step count's fit; ``dptpu calibrate
        response`` shows them on its progress line).

    Raises
    ------
    ValueError
        A capture holds no sequence of :data:`REFERENCE_MIN_STEPS` steps or more; a step count asked for is not
        provided by any capture; no pixel passes the quality masks.
    """
    captures = list(captures)
    available = sorted({n for capture in captures for n in _provided_steps(capture)})
    wanted = available if steps is None else sorted({int(n) for n in steps})
    missing = [n for n in wanted if n not in available]
    if missing:
        raise ValueError(f"no capture provides {', '.join(map(str, missing))}-step phases beside a reference of "
                         f"{REFERENCE_MIN_STEPS}+ steps (available: {', '.join(map(str, available)) or 'none'})")
    step = progress if progress is not None else (lambda label: None)
    pairs: list[_Pair] = []
    for capture in captures:
        step(f"phases of {capture.root}")
        pairs += _pairs_of(capture, min_modulation, wanted)
    fits: dict[int, StepFit] = {}
    for n in wanted:
        step(f"fitting the {n}-step response")
        fits[n] = _fit_steps([pair for pair in pairs if pair.steps == n], multiples)
    return PhaseResponseCalibration(response=ProjectorPhaseResponse({n: fit.error for n, fit in fits.items()}),
                                    fits=fits)


def _references(capture: Capture) -> list[PhaseSequence]:
    """The capture's sequences of :data:`REFERENCE_MIN_STEPS` steps or more; ValueError naming it when none."""
    sequences = capture.phase_sequences
    references = [s for s in sequences if s.steps >= REFERENCE_MIN_STEPS]
    if not references:
        listed = ", ".join(f"{capture.frequency_of(s):g} x {s.steps}" for s in sequences)
        raise ValueError(f"{capture.root / CAPTURE_FILE}: no phase sequence of {REFERENCE_MIN_STEPS} or more steps to "
                         f"calibrate against (has frequency x steps {listed}); the projector's response needs the "
                         f"N-step phases and a {REFERENCE_MIN_STEPS}-step sequence of the same scene")
    return references


def _subset_steps(total: int) -> list[int]:
    """N with ``3 <= N <= total / 2`` dividing ``total``: the N-step sequences inside a ``total``-step one."""
    return [n for n in range(3, total // 2 + 1) if total % n == 0]


def _provided_steps(capture: Capture) -> set[int]:
    """The step counts a capture can calibrate (subsets of its references, its shorter sequences beside them)."""
    provided: set[int] = set()
    for reference in _references(capture):
        provided.update(_subset_steps(reference.steps))
        frequency = capture.frequency_of(reference)
        provided.update(s.steps for s in capture.phase_sequences
                        if s.steps < reference.steps and same_frequency(capture.frequency_of(s), frequency))
    return provided


def _pairs_of(capture: Capture, min_modulation: float | None, wanted: Sequence[int]) -> list[_Pair]:
    """Every (N-step, reference) pair of one capture with N in ``wanted``: subsets of the reference and shorter
    sequences of its frequency."""
    full_scale = float(2 ** capture.bit_depth - 1)
    if min_modulation is None:
        min_modulation = _MIN_MODULATION_FRACTION * full_scale
    where = capture.root / CAPTURE_FILE

    def maps_of(images, sequence: PhaseSequence):
        maps = phase.wrapped_phase(images, shift_sign=capture.phase_shift_sign, phase_offset=sequence.phase_offset)
        ok = phase.quality_mask(images, maps.modulation, min_modulation=min_modulation, saturation_level=full_scale)
        return maps.phase, ok

    pairs = []
    for reference in _references(capture):
        frequency, total = capture.frequency_of(reference), reference.steps
        others = [s for s in capture.phase_sequences if s.steps < total and s.steps in wanted
                  and same_frequency(capture.frequency_of(s), frequency)]
        subsets = [n for n in _subset_steps(total) if n in wanted]
        if not others and not subsets:
            continue
        images = load_sequence_images(capture, reference)  # (M, H, W)
        psi_ref, ok_ref = maps_of(images, reference)
        for n in subsets:
            psi, ok = maps_of(images[:: total // n], reference)
            pairs.append(_Pair(n, frequency, psi, psi_ref, ok & ok_ref, reference.phase_offset,
                               f"{where}: frequency {frequency:g}, {n} of the {total} steps"))
        for other in others:
            psi, ok = maps_of(load_sequence_images(capture, other), other)
            pairs.append(_Pair(other.steps, frequency, psi, psi_ref, ok & ok_ref, other.phase_offset,
                               f"{where}: frequency {frequency:g}, the {other.steps}-step sequence"))
    return pairs


def _fit_steps(pairs: list[_Pair], multiples: int) -> StepFit:
    """The pooled fit of one step count, its residuals and the fit per frequency."""
    steps = pairs[0].steps

    def fit(subset):
        return fit_harmonic_phase_error([np.mod(p.measured + p.phase_offset, 2 * np.pi) for p in subset],
                                        [np.mod(p.reference + p.phase_offset, 2 * np.pi) for p in subset],
                                        [p.valid for p in subset], steps=steps, multiples=multiples)

    error = fit(pairs)
    response = ProjectorPhaseResponse({steps: error})
    before, after = [], []
    for pair in pairs:
        corrected = response.correct(pair.measured, steps, phase_offset=pair.phase_offset)
        before.append(np.angle(np.exp(1j * (pair.measured - pair.reference)))[pair.valid])
        after.append(np.angle(np.exp(1j * (corrected - pair.reference)))[pair.valid])
    frequencies = sorted({p.frequency for p in pairs}, reverse=True)
    by_frequency = {f: fit([p for p in pairs if p.frequency == f]).amplitude_rad for f in frequencies}
    return StepFit(error=error, pixels=int(sum(p.valid.sum() for p in pairs)), pairs=tuple(p.label for p in pairs),
                   rms_before_rad=_rms(before), rms_after_rad=_rms(after), amplitude_by_frequency_rad=by_frequency)


def _rms(parts: list[np.ndarray]) -> float:
    values = np.concatenate(parts)
    return float(np.sqrt(np.mean(values ** 2))) if values.size else float("nan")
