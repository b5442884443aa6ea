"""Gray code + phase shifting: fringe orders from binary code patterns.

Plain Gray code
    ``bits`` binary patterns encode the code-step index ``c = floor(x_p / period)`` of every
    projector coordinate ``x_p`` as a binary-reflected Gray code ``g = c ^ (c >> 1)``, most
    significant bit first, at full on/off levels. One code step is one period of the phase
    sequence it indexes, so the fringe order is ``k = c`` and the absolute phase is
    ``Phi = psi + 2*pi*k`` (Eq. (3) of the paper).

Complementary Gray code (Zhang, Su, Xiang and Sun, Opt. Lasers Eng. 50, 574 (2012))
    One extra pattern, the complementary bit ``b_c = floor(x_p / period + 1/2) mod 2``: stripes one
    period wide (half the finest plain bit's width of two periods), shifted by half a period, so
    its transitions fall at ``x_p = (m + 1/2) * period``, the middles of the phase periods. It is
    exactly the least significant bit of the ``(bits + 1)``-bit Gray code of the half-period index
    ``j = floor(2 x_p / period)``, whose upper ``bits`` bits are the plain patterns. Decoding that
    ``(bits + 1)``-bit code to ``K2`` and taking ``k2 = floor((K2 + 1) / 2)`` gives
    ``k2 = floor(x_p / period + 1/2)``, which changes in the middle of the periods and is immune to
    the plain code's errors at period boundaries (there only the plain bit that flips is uncertain,
    which moves ``K2`` between ``2m - 1`` and ``2m``, both giving ``k2 = m``). With ``k1`` the plain
    code and ``psi`` the wrapped phase in ``[0, 2*pi)``::

        psi <= pi/2          ->  k = k2
        pi/2 < psi < 3*pi/2  ->  k = k1
        psi >= 3*pi/2        ->  k = k2 - 1

    so every pixel uses a code whose transitions are at least a quarter period away.

Convention: ``x_p`` is the 0-based projector coordinate along the fringe axis (the centre of the
first projector pixel is 0) and the wrapped phase of the indexed sequence is
``psi = mod(2*pi*x_p/period, 2*pi)`` in ``[0, 2*pi)``: the code steps and the phase periods start
together at ``x_p = 0``. Bit images are ordered MSB first; a bit is 1 where the pattern is on.

Pixelated projectors: with phase 0 at the centre of projector pixel 0, projector pixel
``m*period`` (the first of code step ``m``) covers ``[m*period - 1/2, m*period + 1/2)``, so a real
projector's code edge sits half a projector pixel before the phase wraps. Plain Gray code then
gives order ``m`` to a camera pixel whose ``psi`` is still near ``2*pi`` on that half-pixel band (an
error of one order); complementary Gray code is exact there (tests pin both).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from dptpu.fpp.checks import check_image_stack, check_projector_size, is_finite_real
from dptpu.fpp.phase import WrappedPhase
from dptpu.fpp.tpu import Unwrapped

__all__ = [
    "GrayCodePatterns",
    "graycode_patterns",
    "decode_graycode",
    "unwrap_graycode",
]

_TWO_PI = 2.0 * np.pi
_DEFAULT_MIN_CONTRAST_FRACTION = 0.05
_WRAP_TOLERANCE_RAD = 1e-9


@dataclass(frozen=True)
class GrayCodePatterns:
    """Projector patterns of a (complementary) Gray code sequence.

    Attributes
    ----------
    images : ndarray (bits, H, W) uint8 or uint16
        Plain Gray code bits, MSB first, at 0 (off) or ``2**bit_depth - 1`` (on).
    inverse : ndarray (bits, H, W) or None
        ``full_scale - images`` when requested.
    complementary : ndarray (H, W) or None
        The complementary bit ``floor(x_p/period + 1/2) mod 2`` at full on/off levels.
    complementary_inverse : ndarray (H, W) or None
        ``full_scale - complementary`` when both inverse and complementary were requested.
    """

    images: np.ndarray
    inverse: np.ndarray | None = None
    complementary: np.ndarray | None = None
    complementary_inverse: np.ndarray | None = None


def graycode_patterns(
    bits,
    period,
    projector_size,
    *,
    axis="x",
    bit_depth=8,
    inverse=False,
    complementary=False,
) -> GrayCodePatterns:
    """Binary-reflected Gray code patterns of the code step ``floor(x_p / period)``.

    Parameters
    ----------
    bits : int
        Number of plain Gray code bits, 1..30; ``2**bits`` code steps must cover the projector
        extent: ``floor((extent - 1) / period) < 2**bits``.
    period : float
        Code step in projector pixels, > 0; equals the period of the phase sequence it indexes.
    projector_size : (int, int)
        Projector ``(width, height)`` in pixels.
    axis : {"x", "y"}
        Coding axis: ``"x"`` codes projector columns (vertical stripes), ``"y"`` rows.
    bit_depth : {8, 16}
        Output ``uint8`` (8) or ``uint16`` (16); on level ``2**bit_depth - 1``.
    inverse : bool
        Also return the inverted patterns (for per-pixel thresholds).
    complementary : bool
        Also return the complementary bit (see the module docstring for its exact definition).

    Returns
    -------
    GrayCodePatterns
        ``images`` (bits, H, W); ``inverse`` (bits, H, W), ``complementary`` (H, W) and
        ``complementary_inverse`` (H, W) when requested, else None.

    Convention: image ``b`` (0-based) holds bit ``bits - 1 - b`` of ``g = c ^ (c >> 1)``
    (MSB first), with ``c = floor(x_p / period)`` and ``x_p`` the 0-based projector pixel along
    ``axis``.
    """
    bits = _bits(bits)
    period = _positive_float(period, "period")
    width, height = check_projector_size(projector_size)
    if axis not in ("x", "y"):
        raise ValueError(f"axis must be 'x' or 'y'; got {axis!r}")
    if bit_depth not in (8, 16):
        raise ValueError(f"bit_depth must be 8 or 16; got {bit_depth!r}")
    extent = width if axis == "x" else height
    code_steps_needed = int(np.floor((extent - 1) / period)) + 1
    if code_steps_needed > 2**bits:
        raise ValueError(
            f"bits={bits} encode {2**bits} code steps but the projector extent {extent} px with "
            f"period {period} px needs {code_steps_needed}; use bits >= "
            f"{int(np.ceil(np.log2(code_steps_needed)))}"
        )

    full_scale = 2**bit_depth - 1
    dtype = np.uint8 if bit_depth == 8 else np.uint16
    x_p = np.arange(extent, dtype=np.float64)  # (extent,)
    code = np.floor(x_p / period).astype(np.int64)  # (extent,)
    bit_rows = _gray_bits(code, bits)  # (bits, extent) 0/1
    comp_row = (np.floor(x_p / period + 0.5).astype(np.int64) & 1).astype(np.uint8)  # (extent,)

    def to_images(rows):  # (..., extent) 0/1 -> (..., H, W) levels
        levels = (rows.astype(np.int64) * full_scale).astype(dtype)
        if axis == "x":
            return np.broadcast_to(levels[..., None, :], levels.shape[:-1] + (height, width)).copy()
        return np.broadcast_to(levels[..., :, None], levels.shape[:-1] + (height, width)).copy()

    images = to_images(bit_rows)
    inverse_images = (full_scale - images).astype(dtype) if inverse else None
    comp_image = to_images(comp_row) if complementary else None
    comp_inverse = (
        (full_scale - comp_image).astype(dtype) if (inverse and complementary) else None
    )
    return GrayCodePatterns(
        images=images,
        inverse=inverse_images,
        complementary=comp_image,
        complementary_inverse=comp_inverse,
    )


def decode_graycode(
    images,
    *,
    inverse=None,
    white=None,
    black=None,
    threshold=None,
    min_contrast=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Decode captured Gray code images to the code-step index of every camera pixel.

    Parameters
    ----------
    images : ndarray (bits, H, W)
        Captured plain Gray code images, MSB first; integer or float dtype, finite.
    inverse : ndarray (bits, H, W), optional
        Captured inverted patterns; bit = ``image > inverse``.
    white, black : ndarray (H, W), optional
        Full-on and full-off reference frames (give both); bit = ``image > (white + black)/2``.
    threshold : float or ndarray broadcastable to (bits, H, W), optional
        A given threshold; bit = ``image > threshold``.
        Give exactly one of ``inverse``, ``white``/``black``, ``threshold``.
    min_contrast : float, optional
        Smallest usable contrast in image intensity units, >= 0. Default: 5% of the brightest value
        among the supplied images (images, inverse, white).

    Returns
    -------
    code : ndarray (H, W) int32
        Decoded code-step index ``c`` in ``[0, 2**bits)`` (Gray -> binary -> integer).
    valid : ndarray (H, W) bool
        Rule: the contrast of a bit is ``|I - I_inv|`` with inverse patterns and ``2|I - t|`` with a
        threshold ``t`` (given, or ``(white + black)/2``); both estimate the on/off swing of a clean
        bit. A pixel is valid where its largest bit contrast is ``>= min_contrast`` (the pixel is
        lit by the projector: not shadowed, not dark) and, with white/black references, where
        ``white - black >= min_contrast``. Low contrast of single bits at code transitions (blur)
        does not invalidate a pixel; use the reliability of :func:`unwrap_graycode` for that.
    """
    stack = _code_stack(images, "images")
    reference, scale = _reference(stack, inverse, white, black, threshold)
    min_contrast = _min_contrast(min_contrast, stack, inverse, white)
    stack = stack.astype(np.float64)  # float so differences of unsigned images cannot wrap
    code_bits = stack > reference  # (bits, H, W)
    contrast = scale * np.abs(stack - reference)  # (bits, H, W)
    code = _gray_to_index(code_bits).astype(np.int32)
    valid = contrast.max(axis=0) >= min_contrast
    if white is not None:
        valid &= (np.asarray(white, np.float64) - np.asarray(black, np.float64)) >= min_contrast
    return code, valid


def unwrap_graycode(
    wrapped,
    images,
    *,
    period,
    inverse=None,
    white=None,
    black=None,
    threshold=None,
    complementary=None,
    complementary_inverse=None,
    min_contrast=None,
    valid=None,
) -> Unwrapped:
    """Absolute phase from a wrapped phase and (complementary) Gray code images.

    Parameters
    ----------
    wrapped : ndarray (H, W) or WrappedPhase
        Wrapped phase ``psi`` of the sequence indexed by the code, radians in ``[0, 2*pi)``
        (map a raw ``arctan2`` phase with ``np.mod(psi, 2*pi)`` first); NaN marks invalid pixels.
    images : ndarray (bits, H, W)
        Captured plain Gray code images, MSB first.
    period : float
        Code step in projector pixels (> 0), equal to the phase sequence's period; the projector
        coordinate is ``x_p = absolute_phase * period / (2*pi)``.
    inverse, white, black, threshold, min_contrast
        Binarization references and validity threshold, as in :func:`decode_graycode`.
    complementary : ndarray (H, W), optional
        Captured complementary bit (see the module docstring); enables complementary decoding.
    complementary_inverse : ndarray (H, W), optional
        Its inverse; required when ``inverse`` is given together with ``complementary``.
    valid : ndarray (H, W) bool, optional
        Pixels to unwrap (e.g. a :func:`dptpu.fpp.phase.quality_mask`); others come back invalid.

    Returns
    -------
    Unwrapped
        The result type of :mod:`dptpu.fpp.tpu`: ``fringe_order`` (H, W) int32 (0 at invalid
        pixels), ``absolute_phase = psi + 2*pi*k`` (H, W) float64 rad (Eq. (3) of the paper; NaN at
        invalid pixels), ``valid`` (H, W) bool, ``reliability`` (H, W) float64 in ``[0, 1]``.

    Notes
    -----
    Plain: ``k = c``, the decoded code. Complementary: ``k1 = c``, ``K2`` the ``(bits+1)``-bit code
    of the plain bits plus the complementary bit, ``k2 = floor((K2 + 1)/2)``; then ``k = k2`` for
    ``psi <= pi/2``, ``k1`` for ``pi/2 < psi < 3*pi/2``, ``k2 - 1`` for ``psi >= 3*pi/2``.

    ``reliability`` is twice the distance, in periods, of ``psi`` from the nearest transition of the
    code actually used (plain code and ``k1``: transitions at ``psi = 0``; ``k2``: at ``psi = pi``),
    i.e. the phase margin against a code edge that is misplaced or blurred: 0 = the pixel sits on a
    code transition (worst), 1 = half a period away (best). Complementary decoding always gives
    ``>= 0.5``. It is 0 where ``valid`` is False. ``valid`` combines the caller's ``valid``, a
    finite ``psi``, the decode validity of :func:`decode_graycode` (including the complementary
    bit's contrast) and an order inside ``[0, 2**bits)``.

    Convention: ``psi`` in ``[0, 2*pi)``, ``k = floor(Phi / 2pi)``; the code steps and phase periods
    both start at projector coordinate 0.
    """
    psi = _wrapped(wrapped)
    if valid is not None:
        valid = np.asarray(valid)
        if valid.dtype != np.bool_ or valid.shape != psi.shape:
            raise ValueError(
                f"valid must be a bool array of shape {psi.shape} like the wrapped phase; "
                f"got dtype {valid.dtype}, shape {valid.shape}"
            )
    stack = _code_stack(images, "images")
    if stack.shape[1:] != psi.shape:
        raise ValueError(
            f"images must have shape (bits, H, W) with (H, W) = {psi.shape} like the wrapped "
            f"phase; got {stack.shape}"
        )
    _positive_float(period, "period")
    bits = stack.shape[0]
    reference, scale = _reference(stack, inverse, white, black, threshold)
    min_contrast = _min_contrast(min_contrast, stack, inverse, white)
    stack = stack.astype(np.float64)  # float so differences of unsigned images cannot wrap
    code_bits = stack > reference  # (bits, H, W)
    contrast = scale * np.abs(stack - reference)  # (bits, H, W)
    code = _gray_to_index(code_bits)  # k1, (H, W) int64
    signal = contrast.max(axis=0)  # (H, W)

    finite = np.isfinite(psi)
    psi = np.where(finite, psi, 0.0)
    fraction = psi / _TWO_PI  # position inside the period, [0, 1)
    distance_to_wrap = np.minimum(fraction, 1.0 - fraction)  # periods to psi = 0 / 2*pi

    if complementary is None:
        if complementary_inverse is not None:
            raise ValueError("complementary_inverse given without complementary")
        order = code
        reliability = 2.0 * distance_to_wrap
    else:
        comp = _code_stack(np.asarray(complementary)[None], "complementary", min_frames=1)
        if comp.shape[1:] != psi.shape:
            raise ValueError(
                f"complementary must have shape (H, W) = {psi.shape}; got {comp.shape[1:]}"
            )
        if inverse is not None:
            if complementary_inverse is None:
                raise ValueError(
                    "complementary_inverse is required when inverse patterns are given "
                    "with a complementary bit"
                )
            comp_inv = _code_stack(
                np.asarray(complementary_inverse)[None], "complementary_inverse", min_frames=1
            )
            if comp_inv.shape != comp.shape:
                raise ValueError(
                    f"complementary_inverse must have shape (H, W) = {psi.shape}; "
                    f"got {comp_inv.shape[1:]}"
                )
            comp_reference = comp_inv[0].astype(np.float64)
        else:
            if complementary_inverse is not None:
                raise ValueError(
                    "complementary_inverse needs inverse patterns for the plain bits too"
                )
            if np.ndim(reference) == 3 and np.shape(reference)[0] != 1:
                raise ValueError(
                    "a per-bit threshold of shape (bits, H, W) does not cover the complementary "
                    "bit; give a threshold broadcastable to (H, W), or white and black references"
                )
            comp_reference = reference[0] if np.ndim(reference) == 3 else reference
        comp_plane = comp[0].astype(np.float64)  # (H, W); float so differences cannot wrap
        comp_bit = comp_plane > comp_reference  # (H, W)
        signal = np.maximum(signal, scale * np.abs(comp_plane - comp_reference))
        extended = np.concatenate([code_bits, comp_bit[None]], axis=0)  # (bits + 1, H, W)
        half_step_index = _gray_to_index(extended)  # K2
        order_half = (half_step_index + 1) // 2  # k2 = floor(x_p/period + 1/2)
        low = psi <= 0.5 * np.pi
        high = psi >= 1.5 * np.pi
        order = np.where(low, order_half, np.where(high, order_half - 1, code))
        distance_to_middle = np.abs(fraction - 0.5)  # periods to psi = pi, k2's transition
        reliability = 2.0 * np.where(low | high, distance_to_middle, distance_to_wrap)

    usable = finite & (signal >= min_contrast) & (order >= 0) & (order < 2**bits)
    if valid is not None:
        usable &= valid
    if white is not None:
        usable &= (np.asarray(white, np.float64) - np.asarray(black, np.float64)) >= min_contrast
    return Unwrapped(
        fringe_order=np.where(usable, order, 0).astype(np.int32),
        absolute_phase=np.where(usable, psi + _TWO_PI * order, np.nan),  # Eq. (3)
        valid=usable,
        reliability=np.where(usable, reliability, 0.0),
    )


def _gray_bits(index, bits) -> np.ndarray:
    """(bits, ...) uint8 0/1: Gray code of an integer index, MSB first."""
    gray = index ^ (index >> 1)
    shifts = np.arange(bits - 1, -1, -1).reshape((bits,) + (1,) * gray.ndim)
    return ((gray[None] >> shifts) & 1).astype(np.uint8)


def _gray_to_index(code_bits) -> np.ndarray:
    """(bits, H, W) bool Gray bits, MSB first -> (H, W) int64 integer index."""
    binary = np.bitwise_xor.accumulate(code_bits.astype(np.int64), axis=0)  # binary bits, MSB first
    index = np.zeros(code_bits.shape[1:], dtype=np.int64)
    for bit in binary:  # loop over bits, not pixels
        index = (index << 1) | bit
    return index


def _reference(stack, inverse, white, black, threshold):
    """Per-bit binarization reference and the factor that turns |I - ref| into an on/off swing."""
    given = [inverse is not None, white is not None or black is not None, threshold is not None]
    if sum(given) != 1:
        raise ValueError(
            "give exactly one binarization reference: inverse, white and black, or threshold; "
            f"got inverse={'set' if given[0] else None}, white/black="
            f"{'set' if given[1] else None}, threshold={'set' if given[2] else None}"
        )
    if inverse is not None:
        inverse = _code_stack(inverse, "inverse")
        if inverse.shape != stack.shape:
            raise ValueError(
                f"inverse must have the shape of images {stack.shape}; got {inverse.shape}"
            )
        return inverse.astype(np.float64), 1.0
    if white is not None or black is not None:
        if white is None or black is None:
            raise ValueError("white and black references must be given together")
        planes = []
        for name, plane in (("white", white), ("black", black)):
            plane = _code_stack(np.asarray(plane)[None], name, min_frames=1)
            if plane.shape[1:] != stack.shape[1:]:
                raise ValueError(
                    f"{name} must have shape (H, W) = {stack.shape[1:]}; got {plane.shape[1:]}"
                )
            planes.append(plane[0].astype(np.float64))
        return 0.5 * (planes[0] + planes[1]), 2.0
    threshold = np.asarray(threshold, dtype=np.float64)
    if not np.all(np.isfinite(threshold)):
        raise ValueError("threshold contains NaN or inf")
    try:
        np.broadcast_shapes(threshold.shape, stack.shape)
    except ValueError:
        raise ValueError(
            f"threshold must be a scalar or broadcastable to images {stack.shape}; "
            f"got shape {threshold.shape}"
        ) from None
    return threshold, 2.0


def _min_contrast(min_contrast, stack, inverse, white) -> float:
    if min_contrast is None:
        brightest = float(stack.max())
        for extra in (inverse, white):
            if extra is not None:
                brightest = max(brightest, float(np.max(extra)))
        return _DEFAULT_MIN_CONTRAST_FRACTION * brightest
    if not is_finite_real(min_contrast) or min_contrast < 0:
        raise ValueError(f"min_contrast must be a finite number >= 0; got {min_contrast!r}")
    return float(min_contrast)


def _wrapped(wrapped) -> np.ndarray:
    if isinstance(wrapped, WrappedPhase):
        wrapped = wrapped.phase
    psi = np.asarray(wrapped)
    if psi.ndim != 2:
        raise ValueError(f"wrapped phase must have shape (H, W); got {psi.shape}")
    if not np.issubdtype(psi.dtype, np.floating):
        raise ValueError(f"wrapped phase must be a float array in radians; got {psi.dtype}")
    psi = psi.astype(np.float64)
    finite_values = psi[~np.isnan(psi)]
    if not np.isfinite(finite_values).all():
        raise ValueError("wrapped phase must not contain inf; mark invalid pixels with NaN instead")
    if finite_values.size and (
        finite_values.min() < -_WRAP_TOLERANCE_RAD
        or finite_values.max() >= _TWO_PI + _WRAP_TOLERANCE_RAD
    ):
        raise ValueError(
            "wrapped phase must lie in [0, 2*pi); got values in "
            f"[{finite_values.min():.6g}, {finite_values.max():.6g}] "
            "(map a phase in (-pi, pi] with np.mod(psi, 2*pi))"
        )
    psi = np.mod(psi, _TWO_PI)  # fold the tolerance band back into [0, 2*pi)
    psi[psi >= _TWO_PI] = 0.0
    return psi


def _bits(bits) -> int:
    if isinstance(bits, bool) or not isinstance(bits, numbers.Integral) or not 1 <= int(bits) <= 30:
        raise ValueError(f"bits must be an integer in 1..30; got {bits!r}")
    return int(bits)


def _positive_float(value, name) -> float:
    if not is_finite_real(value):
        raise ValueError(f"{name} must be a finite real number; got {value!r}")
    if value <= 0:
        raise ValueError(f"{name} must be > 0; got {value}")
    return float(value)


def _code_stack(images, name, *, min_frames=1) -> np.ndarray:
    return check_image_stack(images, name, min_frames=min_frames, max_frames=30, what="bits")
