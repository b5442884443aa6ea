"""Wrapped phase, modulation and background from an N-step phase-shifted image stack.

The model (Eq. (1) of the paper, generalized to either shift sign and a constant offset) is

    I_n = A + B cos(psi + delta_n),    delta_n = phase_offset + shift_sign * 2*pi*n/N,

for ``n = 0..N-1``. The least-squares estimate (Eq. (2) of the paper) is

    S = -sum_n I_n sin(delta_n) = (N/2) B sin(psi)
    C =  sum_n I_n cos(delta_n) = (N/2) B cos(psi)
    psi = atan2(S, C) mod 2*pi,  B = (2/N) sqrt(S^2 + C^2),  A = mean_n I_n,

exact for any ``N >= 3`` because the ``delta_n`` are equally spaced over a full turn.

Convention: wrapped phase is in ``[0, 2*pi)``, so ``phi = psi + 2*pi*k`` with
``k = floor(phi / 2pi)`` (Eq. (3) of the paper); ``shift_sign = -1`` is the paper's Eq. (1).

Speed: the three sums are one (3, N) @ (N, H*W) matrix product, in float32 for 8/16-bit images (exact
inputs; the phase is then within about 5e-7 rad of the float64 result), float64 otherwise; kernels in
:mod:`._lsq_phase`. Timings: docs/benchmarks.md (``dptpu bench fpp``).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from ._lsq_phase import angle_0_2pi_float32, angle_0_2pi_float64, phase_sums
from .checks import check_image_stack, is_finite_real

__all__ = ["WrappedPhase", "wrapped_phase", "quality_mask", "check_bit_depth", "sequence_sums", "maps_from_sums",
           "modulation_from_sums"]

_TWO_PI = 2.0 * np.pi
#: Integer image dtypes whose values float32 holds exactly: their sums are computed in float32.
_FLOAT32_EXACT = (np.uint8, np.int8, np.uint16, np.int16)


@dataclass(frozen=True)
class WrappedPhase:
    """The wrapped phase, modulation and background of one N-step sequence (what :func:`wrapped_phase` returns).

    Not the wire message :class:`dptpu.messages.PhaseMaps`, which carries a whole scan's maps between nodes.

    Attributes
    ----------
    phase : ndarray (H, W) float64 (or float32 on request)
        Wrapped phase ``psi`` in radians, in ``[0, 2*pi)``.
    modulation : ndarray (H, W) float64 (or float32)
        Fringe modulation ``B`` in the images' intensity units (>= 0).
    background : ndarray (H, W) float64 (or float32)
        Background intensity ``A`` in the images' intensity units.
    """

    phase: np.ndarray
    modulation: np.ndarray
    background: np.ndarray


def wrapped_phase(images, *, shift_sign=-1, phase_offset=0.0, bit_depth=None, dtype=np.float64) -> WrappedPhase:
    """Least-squares wrapped phase of an N-step sequence (Eq. (2) of the paper).

    Parameters
    ----------
    images : ndarray (N, H, W)
        Phase-shifted images, ``N >= 3``, step order ``n = 0..N-1``; uint8, uint16, other integer
        or float dtype, finite.
    shift_sign : {-1, +1}
        Image ``n`` is ``A + B cos(psi + phase_offset + shift_sign*2*pi*n/N)``; -1 is Eq. (1).
    phase_offset : float
        Constant phase offset of the sequence in radians.
    bit_depth : int, optional
        If given, the images are checked against it first (see :func:`check_bit_depth`).
    dtype : {numpy.float64, numpy.float32}
        Dtype of the returned maps (float64 by default; float32 saves the casts where float32 is what
        is kept, e.g. the phase node's messages).

    Returns
    -------
    WrappedPhase
        ``phase`` (H, W) in ``[0, 2*pi)`` rad, ``modulation`` ``B`` and ``background`` ``A``
        (H, W) in the images' intensity units, all of ``dtype``.

    Notes
    -----
    ``S = -sum_n I_n sin(delta_n)``, ``C = sum_n I_n cos(delta_n)`` with
    ``delta_n = phase_offset + shift_sign*2*pi*n/N``; ``psi = atan2(S, C) mod 2*pi``,
    ``B = (2/N) sqrt(S^2 + C^2)``, ``A = mean(I_n)``. For ``shift_sign = -1`` and no offset this is
    Eq. (2) of the paper. With additive Gaussian intensity noise ``sigma`` the phase noise is
    ``sqrt(2/N) * sigma / B`` rad.

    Convention: phase in ``[0, 2*pi)``, so the fringe order is ``k = floor(phi / 2pi)``.
    Precision: 8- and 16-bit integer images are summed in float32 (their values are exact in it) and the
    arctangent is float32-accurate: for ``N <= 24`` the phase is within about ``5e-7 + 3e-7 * A / B`` rad of
    the float64 computation (measured 4e-7 rad at A = 128, B = 100 DN, 8-bit; 2e-5 rad at A = 30000,
    B = 300 DN, 16-bit, where the noise is ~1e-3 rad), ``B`` and ``A`` within a relative 1e-6; every other
    dtype is computed in float64.
    """
    images = check_image_stack(images)
    if shift_sign not in (-1, 1):
        raise ValueError(f"shift_sign must be -1 or +1; got {shift_sign!r}")
    if not is_finite_real(phase_offset):
        raise ValueError(
            f"phase_offset must be a finite real number (radians); got {phase_offset!r}"
        )
    if np.dtype(dtype) not in (np.float32, np.float64):
        raise ValueError(f"dtype must be float32 or float64; got {np.dtype(dtype)}")
    if bit_depth is not None:
        check_bit_depth(images, bit_depth)

    single = images.dtype in _FLOAT32_EXACT and images.shape[1] * images.shape[2] > 0
    sine, cosine, background = phase_sums(images, shift_sign=shift_sign, phase_offset=phase_offset,
                                          dtype=np.float32 if single else np.float64)  # (H, W) each
    if single:
        modulation = modulation_from_sums(sine, cosine)
        phase = angle_0_2pi_float32(sine, cosine, modulation)
    else:
        modulation = np.hypot(sine, cosine)
        phase = angle_0_2pi_float64(sine, cosine)
    return WrappedPhase(phase=phase.astype(dtype, copy=False), modulation=modulation.astype(dtype, copy=False),
                     background=background.astype(dtype, copy=False))


def sequence_sums(images, *, shift_sign=-1, phase_offset=0.0) -> np.ndarray:
    """The sums of Eq. (2) of an 8/16-bit (N, H, W) stack: ``B sin(psi)``, ``B cos(psi)``, ``A`` as one (3, H, W)
    float32 array; :func:`maps_from_sums` turns them into the maps, the two together being :func:`wrapped_phase`
    (the same sums, the same maps bit for bit).

    For a caller that works sequence by sequence as images arrive (the phase node computes each entry's sums as
    soon as its images are in, so after a scan's last image only its last entry is left). ``images``,
    ``shift_sign`` and ``phase_offset`` as in :func:`wrapped_phase`; the dtype must be uint8, int8, uint16 or
    int16 (ValueError otherwise).
    """
    images = check_image_stack(images)
    if images.dtype not in _FLOAT32_EXACT:
        raise ValueError(f"images must be 8- or 16-bit integers for float32 sums; got {images.dtype}")
    if shift_sign not in (-1, 1):
        raise ValueError(f"shift_sign must be -1 or +1; got {shift_sign!r}")
    return phase_sums(images, shift_sign=shift_sign, phase_offset=float(phase_offset), dtype=np.float32)


def modulation_from_sums(sine: np.ndarray, cosine: np.ndarray) -> np.ndarray:
    """The modulation ``B = sqrt((B sin psi)^2 + (B cos psi)^2)`` (H, W) float32 of Eq. (2)'s float32 sums.

    The same bits at any memory alignment of the inputs: numpy's float32 multiply, add and square root round each
    element correctly whichever SIMD or scalar path serves it. OpenCV's ``cv2.magnitude`` (used before) rounds
    about one element in 300,000 one ulp apart when an array starts at another address, so two runs of the same
    scan could differ by a point of ~270,000 (a modulation on the threshold). Both values lie within 1 ulp of the
    exact magnitude (the sums of N 16-bit images are at most N x 65535 in size: their squares cannot overflow
    float32).
    """
    modulation = np.multiply(cosine, cosine)
    modulation += np.square(sine)
    return np.sqrt(modulation, out=modulation)


def maps_from_sums(sums: np.ndarray, modulation: np.ndarray | None = None) -> WrappedPhase:
    """Phase in ``[0, 2*pi)``, modulation ``B`` and background ``A`` (H, W) float32 from the sums of Eq. (2).

    ``sums`` (3, H, W) float32 holds ``B sin(psi)``, ``B cos(psi)`` and ``A`` (:func:`sequence_sums`);
    ``modulation``: :func:`modulation_from_sums` of them when the caller has it already (None: computed here).
    """
    sine, cosine, background = sums
    if modulation is None:
        modulation = modulation_from_sums(sine, cosine)
    return WrappedPhase(phase=angle_0_2pi_float32(sine, cosine, modulation), modulation=modulation,
                     background=background)


def quality_mask(images, modulation, *, min_modulation, saturation_level=None) -> np.ndarray:
    """Pixels whose phase can be trusted: enough modulation and no saturated frame.

    Parameters
    ----------
    images : ndarray (N, H, W)
        The phase-shifted images the modulation came from.
    modulation : ndarray (H, W)
        Modulation ``B`` in the images' intensity units (e.g. ``WrappedPhase.modulation``).
    min_modulation : float
        Smallest acceptable ``B``, >= 0, in the images' intensity units.
    saturation_level : float, optional
        A pixel is saturated when any frame reaches this level (``>=``). Default: the dtype's
        maximum for integer images (255 for uint8, 65535 for uint16); no saturation check for
        float images.

    Returns
    -------
    ndarray (H, W) bool
        True where ``modulation >= min_modulation`` and ``max_n I_n < saturation_level``;
        NaN modulation is False.
    """
    images = check_image_stack(images)
    modulation = np.asarray(modulation)
    if modulation.shape != images.shape[1:]:
        raise ValueError(
            f"modulation must have shape (H, W) = {images.shape[1:]} like the images; "
            f"got {modulation.shape}"
        )
    if not is_finite_real(min_modulation) or min_modulation < 0:
        raise ValueError(f"min_modulation must be a finite number >= 0; got {min_modulation!r}")
    if saturation_level is None and np.issubdtype(images.dtype, np.integer):
        saturation_level = np.iinfo(images.dtype).max
    mask = modulation >= min_modulation  # (H, W); NaN compares False
    if saturation_level is not None:
        if isinstance(saturation_level, bool) or not isinstance(saturation_level, numbers.Real):
            raise ValueError(f"saturation_level must be a real number; got {saturation_level!r}")
        mask &= ~(images.max(axis=0) >= saturation_level)  # one pass: any frame at the level
    return mask


def check_bit_depth(images, bit_depth) -> None:
    """Raise ValueError when images do not fit the declared bit depth.

    Parameters
    ----------
    images : ndarray (..., H, W)
        Images of any shape; integer or float dtype.
    bit_depth : int
        Declared bit depth, 1..16; values must lie in ``[0, 2**bit_depth - 1]``.

    Raises
    ------
    ValueError
        When ``bit_depth`` is invalid; when the dtype cannot hold the declared depth (e.g.
        uint8 declared 16-bit: the high bits were lost); when values are NaN/inf, negative, or
        exceed ``2**bit_depth - 1`` (e.g. "image values reach 4095 but bit_depth is 8").
    """
    if isinstance(bit_depth, bool) or not isinstance(bit_depth, numbers.Integral) or not (
        1 <= int(bit_depth) <= 16
    ):
        raise ValueError(f"bit_depth must be an integer in 1..16; got {bit_depth!r}")
    bit_depth = int(bit_depth)
    images = np.asarray(images)
    dtype = images.dtype
    if not (np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.floating)):
        raise ValueError(f"images must have an integer or float dtype; got {dtype}")
    if np.issubdtype(dtype, np.integer):
        value_bits = np.iinfo(dtype).bits - (1 if np.issubdtype(dtype, np.signedinteger) else 0)
        if value_bits < bit_depth:
            raise ValueError(
                f"images of dtype {dtype} cannot hold {bit_depth}-bit values "
                f"(at most {value_bits} bits); expected uint16 for bit_depth {bit_depth}"
            )
    elif not np.all(np.isfinite(images)):
        raise ValueError("images contain NaN or inf; cannot check bit_depth")
    if images.size == 0:
        return
    full_scale = 2**bit_depth - 1
    lowest = images.min()
    highest = images.max()
    if lowest < 0:
        raise ValueError(f"image values reach {lowest} but must be >= 0 for bit_depth {bit_depth}")
    if highest > full_scale:
        raise ValueError(
            f"image values reach {highest} but bit_depth is {bit_depth} (max {full_scale})"
        )


