"""Absolute phase of a capture folder: wrapped phase of its sequences, then temporal phase unwrapping.

:func:`unwrap_capture` is the one call from a ``dptpu-capture/1`` folder (:mod:`dptpu.fpp.capture`) to
the fringe order and absolute phase of its highest-frequency phase sequence, by one of the methods

========== ================================================================== ===========================
method     sequences used (defaults)                                          equations of the paper
========== ================================================================== ===========================
mf         high = highest frequency, low = lowest (needs ``f_l <= 1``)         Eq. (5)
mw         high, low = the sequence with ``0 < f_h - f_l <= 1`` (largest gap)  Eqs. (6)-(7)
nt         high, low = the only other phase sequence                           Eqs. (8)-(9)
heterodyne every phase sequence (beat tree down to a beat ``<= 1``)            Eqs. (6)-(7), hierarchical
graycode   the phase sequence whose period is the Gray code's, + the code      Eq. (3)
========== ================================================================== ===========================

``high`` and ``low`` select sequences by frequency (periods across the projector extent), matched by
:func:`dptpu.fpp.frequencies.same_frequency` (within a relative ``1e-3``, so ``45.714`` finds ``1920 / 42``);
the choice of the sequences is :func:`dptpu.fpp.frequencies.select_frequencies`, the unwrap node's too.

Validity: a pixel is valid where the unwrapping method accepts it AND every phase sequence it used has
modulation ``B >= min_modulation`` and no saturated frame (:func:`dptpu.fpp.phase.quality_mask`) and a phase
noise, measured from its own fit, below ``max_noise_ratio`` times the scan's median (:mod:`dptpu.fpp.fringe_noise`)
AND its absolute phase lies on the projector, ``0 <= absolute_phase < 2*pi*f`` (an order that puts a pixel
outside the projector is wrong: a noisy pixel, or a capture whose ``phase_shift_sign`` is wrong). The
default ``min_modulation`` is :data:`DEFAULT_MIN_MODULATION_FRACTION` (2 %) of the camera's full scale
``2**bit_depth - 1`` (5.1 digital numbers for 8-bit frames); a frame reaching full scale is saturated.

Convention: the capture's ``phase_shift_sign`` and each sequence's ``phase_offset`` are honoured, so
every wrapped phase is ``psi = mod(2*pi*f*x_p/W_p, 2*pi)`` in ``[0, 2*pi)`` whatever the projector's
step direction, ``absolute_phase = psi + 2*pi*k`` with ``k = floor(absolute_phase / 2pi)``, and the
projector coordinate is ``x_p = absolute_phase * W_p / (2*pi*f)`` (``W_p`` = projector extent along
``fringe_axis``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from . import graycode, phase, tpu
from .capture import (
    Capture,
    GraycodeSequence,
    PhaseSequence,
    load_image,
    load_images,
    load_reference,
    load_sequence_images,
)
from .frequencies import find_frequency, same_frequency, select_frequencies
from .fringe_noise import DEFAULT_MAX_NOISE_RATIO, noise_outliers, sequence_phase_noise
from .methods import CAPTURE_METHODS
from .nt_twins import twin_ambiguous
from .phase_harmonics import ProjectorPhaseResponse

__all__ = ["DEFAULT_MIN_MODULATION_FRACTION", "CaptureResult", "unwrap_capture"]

#: Default ``min_modulation`` as a fraction of the camera's full scale ``2**bit_depth - 1``.
DEFAULT_MIN_MODULATION_FRACTION = 0.02


@dataclass(frozen=True, eq=False)
class CaptureResult:
    """Absolute phase of a capture's highest-frequency (or chosen ``high``) phase sequence.

    Attributes
    ----------
    fringe_order : ndarray (H, W) int32
        Fringe order ``k`` of the high sequence; 0 where the method did not unwrap the pixel.
    absolute_phase : ndarray (H, W) float64
        ``psi + 2*pi*k`` in radians (Eq. (3) of the paper), ``phi = 2*pi*f*x_p/W_p``; NaN or
        meaningless where ``valid`` is False.
    valid : ndarray (H, W) bool
        Unwrapped by the method, passing the quality mask of every sequence used, and with
        ``0 <= absolute_phase < 2*pi*frequency`` (on the projector).
    modulation : ndarray (H, W) float64
        Modulation ``B`` of the high sequence, camera digital numbers.
    reliability : ndarray (H, W) float64
        The method's margin in ``[0, 1]`` (:mod:`dptpu.fpp.confidence`; Gray code: the distance to a code
        edge); 0 where the method rejected the pixel.
    frequency : float
        Frequency ``f`` of the high sequence (periods across ``W_p``).
    method : str
        One of :data:`dptpu.fpp.methods.CAPTURE_METHODS`.
    frequencies : tuple of float
        Frequencies of the phase sequences used, the high one first.
    fringe_axis : str
        ``"x"`` or ``"y"``, from the capture.
    projector_size : (int, int)
        Projector ``(width, height)``, from the capture.
    wrapped_phases : tuple of ndarray (H, W) float64
        Wrapped phase ``psi`` in ``[0, 2*pi)`` of each sequence in ``frequencies`` (so a fringe-order
        refinement, e.g. the DP-TPU network in ``dptpu.models``, can start from this result).
    quality : ndarray (H, W) bool or None
        Quality mask of the sequences used (modulation, saturation), before unwrapping.
    steps : tuple of int
        Phase steps of the sequences in ``frequencies``.
    quantization_noise : tuple of (ndarray (H, W) float32 or None)
        Per sequence in ``frequencies``, the phase noise the images' rounding to whole digital numbers leaves at each
        pixel (:func:`dptpu.fpp.fringe_noise.quantization_phase_noise`; None for float images); empty when unknown.
    """

    fringe_order: np.ndarray
    absolute_phase: np.ndarray
    valid: np.ndarray
    modulation: np.ndarray
    reliability: np.ndarray
    frequency: float
    method: str
    frequencies: tuple[float, ...]
    fringe_axis: str
    projector_size: tuple[int, int]
    wrapped_phases: tuple[np.ndarray, ...] = ()
    quality: np.ndarray | None = None
    steps: tuple[int, ...] = ()
    quantization_noise: tuple[np.ndarray | None, ...] = ()

    @property
    def fringe_extent_px(self) -> int:
        """Projector extent ``W_p`` along the fringe axis, projector pixels."""
        return self.projector_size[0] if self.fringe_axis == "x" else self.projector_size[1]

    @property
    def valid_count(self) -> int:
        """Number of valid pixels."""
        return int(np.count_nonzero(self.valid))


def unwrap_capture(
    capture: Capture,
    *,
    method: str,
    high: float | None = None,
    low: float | None = None,
    min_modulation: float | None = None,
    saturation_level: float | None = None,
    phase_response: ProjectorPhaseResponse | None = None,
    max_noise_ratio: float = DEFAULT_MAX_NOISE_RATIO,
) -> CaptureResult:
    """Fringe order and absolute phase of a capture by temporal phase unwrapping.

    Parameters
    ----------
    capture : Capture
        From :func:`dptpu.fpp.capture.read_capture`.
    method : {"mf", "mw", "nt", "heterodyne", "graycode"}
        See the module docstring for the sequences each one uses.
    high, low : float, optional
        Frequencies (periods across the projector extent) of the sequences to use; default as in the
        module docstring. ``heterodyne`` uses every phase sequence and takes neither; ``graycode``
        takes only ``high``.
    min_modulation : float, optional
        Smallest modulation ``B`` (camera digital numbers) of a valid pixel; default
        ``DEFAULT_MIN_MODULATION_FRACTION * (2**bit_depth - 1)``.
    saturation_level : float, optional
        A pixel with any frame ``>=`` this level is invalid; default the full scale
        ``2**bit_depth - 1``.
    phase_response : ProjectorPhaseResponse, optional
        The projector's calibrated response (the rig file's ``projector.phase_response``): the harmonic phase
        error of each sequence whose step count it holds is removed from its wrapped phase before unwrapping
        (:meth:`dptpu.fpp.phase_harmonics.ProjectorPhaseResponse.correct`); other sequences, and every sequence
        without it, are used as computed.
    max_noise_ratio : float, optional
        A pixel whose phase noise, measured from its own N-step fit (``N >= 5``), is at least this many times the
        scan's median in any sequence used is invalid (:func:`dptpu.fpp.fringe_noise.noise_outliers`); 0: no
        such test. Default :data:`dptpu.fpp.fringe_noise.DEFAULT_MAX_NOISE_RATIO`.

    Returns
    -------
    CaptureResult

    Raises
    ------
    ValueError
        Unknown method; no sequence of the requested frequency (the message lists those present); the
        capture lacks what the method needs (e.g. ``mw`` without a pair ``0 < f_h - f_l <= 1``,
        ``graycode`` without a Gray-code sequence); bad frames (see
        :func:`dptpu.fpp.capture.load_image`).

    Notes
    -----
    Wrapped phase by Eq. (2) (generalized to the capture's step sign and offset), fringe order by
    Eq. (5) (mf), Eqs. (6)-(7) (mw, heterodyne), Eqs. (8)-(9) (nt) or the Gray code, absolute phase by
    Eq. (3).
    """
    if method not in CAPTURE_METHODS:
        raise ValueError(f"unknown unwrapping method {method!r}; expected one of {', '.join(CAPTURE_METHODS)}")
    full_scale = float(2**capture.bit_depth - 1)
    if min_modulation is None:
        min_modulation = DEFAULT_MIN_MODULATION_FRACTION * full_scale
    if saturation_level is None:
        saturation_level = full_scale

    if method == "graycode":
        phase_sequences, code = _select_graycode(capture, high, low)
    else:
        phase_sequences, code = _select_phase_sequences(capture, method, high, low), None
    frequencies = [capture.frequency_of(s) for s in phase_sequences]

    maps, quality, noise, floors = [], np.ones(capture.image_shape, dtype=bool), [], []
    for sequence in phase_sequences:
        images = load_sequence_images(capture, sequence)  # (N, H, W)
        sequence_maps = phase.wrapped_phase(
            images, shift_sign=capture.phase_shift_sign, phase_offset=sequence.phase_offset
        )
        quality &= phase.quality_mask(
            images, sequence_maps.modulation, min_modulation=min_modulation, saturation_level=saturation_level
        )
        maps.append(sequence_maps)
        sequence_noise, floor = sequence_phase_noise(images, sequence_maps.background, sequence_maps.modulation,
                                                     measure=max_noise_ratio > 0)
        noise.append(sequence_noise)
        floors.append(floor)
    quality &= ~noise_outliers(noise, quality, max_noise_ratio, floors)

    psi = [m.phase for m in maps]
    if phase_response is not None:
        psi = [phase_response.correct(p, s.steps, phase_offset=s.phase_offset) for p, s in zip(psi, phase_sequences)]
    f_h = frequencies[0]
    if method == "mf":
        unwrapped = tpu.unwrap_mf(psi[0], psi[1], f_h, frequencies[1], valid=quality)
    elif method == "mw":
        unwrapped = tpu.unwrap_mw(psi[0], psi[1], f_h, frequencies[1], valid=quality)
    elif method == "nt":
        unwrapped = tpu.unwrap_nt(psi[0], psi[1], f_h, frequencies[1], capture.fringe_extent_px, valid=quality)
        # an order that neither its pixel nor its region tells from a near-twin within the noise's reach: no confidence
        twins = twin_ambiguous(unwrapped.absolute_phase, psi[1], f_h, frequencies[1], unwrapped.valid,
                               modulation=maps[0].modulation)
        unwrapped = dataclasses.replace(unwrapped, reliability=np.where(twins, 0.0, unwrapped.reliability))
    elif method == "heterodyne":
        unwrapped = tpu.unwrap_heterodyne(psi, frequencies, valid=quality)
    else:  # "graycode"
        if code is None:  # _select_graycode returns the Gray-code sequence or raises
            raise RuntimeError("graycode unwrapping reached without a Gray-code sequence")
        unwrapped = _unwrap_graycode(capture, code, maps[0], psi[0])

    absolute_phase = np.asarray(unwrapped.absolute_phase, dtype=np.float64)  # (H, W)
    with np.errstate(invalid="ignore"):  # NaN at pixels the method rejected
        on_projector = (absolute_phase >= 0.0) & (absolute_phase < 2.0 * np.pi * f_h)
    valid = np.asarray(unwrapped.valid, dtype=bool) & quality & on_projector
    return CaptureResult(
        fringe_order=np.asarray(unwrapped.fringe_order, dtype=np.int32),
        absolute_phase=absolute_phase,
        valid=valid,
        modulation=maps[0].modulation,
        reliability=np.where(valid, unwrapped.reliability, 0.0),
        frequency=float(f_h),
        method=method,
        frequencies=tuple(float(f) for f in frequencies),
        fringe_axis=capture.fringe_axis,
        projector_size=(capture.projector_size[0], capture.projector_size[1]),
        wrapped_phases=tuple(psi),
        quality=quality,
        steps=tuple(s.steps for s in phase_sequences),
        quantization_noise=tuple(floors),
    )


# --------------------------------------------------------------------------------------------------
# Choosing sequences
# --------------------------------------------------------------------------------------------------

def _select_phase_sequences(capture: Capture, method: str, high, low) -> list[PhaseSequence]:
    """The phase sequences a TPU method uses, the high one first (:func:`dptpu.fpp.frequencies.select_frequencies`)."""
    sequences = capture.phase_sequences
    chosen = select_frequencies(method, [capture.frequency_of(s) for s in sequences], high=high, low=low,
                                options=("--high", "--low"), context=f"the capture has {_list_frequencies(capture)}")
    return [sequences[i] for i in chosen]


def _select_graycode(capture: Capture, high, low) -> tuple[list[PhaseSequence], GraycodeSequence]:
    """The phase sequence a Gray-code sequence indexes (period equal to the code step), and the code."""
    if low is not None:
        raise ValueError("graycode uses one phase sequence and the Gray code; --low does not apply to it")
    codes = capture.graycode_sequences
    if not codes:
        raise ValueError("graycode needs a sequence of kind 'graycode'; the capture has none "
                         f"(it has {_list_frequencies(capture)})")
    sequences = capture.phase_sequences
    phase_sequences = (
        [sequences[find_frequency([capture.frequency_of(s) for s in sequences], high, option="--high",
                                  context=f"the capture has {_list_frequencies(capture)}")]]
        if high is not None else sorted(sequences, key=lambda s: -capture.frequency_of(s))
    )
    for sequence in phase_sequences:
        f = capture.frequency_of(sequence)
        for code in codes:
            if same_frequency(capture.frequency_of(code), f):
                return [sequence], code
    periods = ", ".join(f"{c.period:g}" for c in codes)
    raise ValueError(f"no phase sequence has the period of the Gray code (period {periods} projector pixels, "
                     f"frequency {', '.join(f'{capture.frequency_of(c):g}' for c in codes)}); "
                     f"the capture has {_list_frequencies(capture)}")


def _list_frequencies(capture: Capture) -> str:
    parts = []
    for s in capture.phase_sequences:
        f = capture.frequency_of(s)
        parts.append(f"{f:g}" if s.frequency is not None else f"{f:g} (period {s.period:g})")
    return "phase sequences of frequency " + ", ".join(parts)


# --------------------------------------------------------------------------------------------------
# Gray code
# --------------------------------------------------------------------------------------------------

def _unwrap_graycode(capture: Capture, code: GraycodeSequence, maps: phase.WrappedPhase, psi: np.ndarray):
    """Binarize with the inverse patterns, else the white/black references, else the phase background.

    The last fallback thresholds each bit at the background ``A`` of the indexed phase sequence, which
    is the mid level between the code's on and off frames when the fringe offset is half of full scale
    (the usual ``pattern.offset: 0.5``). ``psi`` is the wrapped phase of ``maps`` (corrected for the projector's
    response where the rig holds one).
    """
    images = load_sequence_images(capture, code)  # (bits, H, W)
    options = {}
    if code.complementary is not None:
        options["complementary"] = load_image(capture, code.complementary)
    white, black = load_reference(capture, "white"), load_reference(capture, "black")
    if code.inverse is not None:
        options["inverse"] = load_images(capture, code.inverse)  # (bits, H, W)
        if code.complementary is not None:  # the reader guarantees its inverse then
            options["complementary_inverse"] = load_image(capture, code.complementary_inverse)
    elif white is not None and black is not None:
        options["white"], options["black"] = white, black
    else:
        options["threshold"] = maps.background[None]  # (1, H, W)
    return graycode.unwrap_graycode(psi, images, period=code.period, **options)
