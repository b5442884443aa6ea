"""Phase-shifted sinusoidal fringe patterns for the projector.

Image ``n`` (0-based) of an ``N``-step sequence is

    I_n = offset + amplitude * cos(phi + phase_offset + shift_sign * 2*pi*n/N)

as a fraction of the projector's full scale, with ``phi = 2*pi*f*x_p/W`` the absolute phase of
projector pixel ``x_p`` (Eq. (1) of the paper for ``shift_sign = -1``).

Convention: ``x_p`` is the 0-based projector coordinate along the fringe axis; the centre of the
first projector pixel is ``x_p = 0``, so pixel ``i`` has phase exactly ``2*pi*f*i/W``. With
``axis="x"`` the phase grows with the projector column (vertical stripes), ``W`` is the projector
width; with ``axis="y"`` it grows with the row and ``W`` is the projector height.
"""

from __future__ import annotations

import numbers

import numpy as np

from .checks import check_projector_size

__all__ = ["frequency_from_period", "projector_phase", "fringe_patterns"]

_AXES = ("x", "y")
_BIT_DEPTHS = (8, 16)


def frequency_from_period(period, extent) -> float:
    """Number of fringe periods across the projector extent, ``f = extent / period``.

    Parameters
    ----------
    period : float
        Length of one fringe period in projector pixels, > 0.
    extent : float
        Projector extent ``W`` along the fringe axis in projector pixels, > 0 (the width for
        ``axis="x"``, the height for ``axis="y"``).

    Returns
    -------
    float
        Frequency ``f`` in periods per projector extent (may be rational, e.g. 10.9).
    """
    period = _positive_float(period, "period")
    extent = _positive_float(extent, "extent")
    return extent / period


def projector_phase(projector_size, frequency, *, axis="x") -> np.ndarray:
    """Absolute phase ``phi = 2*pi*f*x_p/W`` of every projector pixel.

    Parameters
    ----------
    projector_size : (int, int)
        Projector ``(width, height)`` in pixels.
    frequency : float
        Number of fringe periods ``f`` across the extent ``W`` along the fringe axis, > 0.
    axis : {"x", "y"}
        Fringe axis: ``"x"`` means phase varies along projector columns (``W`` = width),
        ``"y"`` along rows (``W`` = height).

    Returns
    -------
    ndarray (H, W) float64
        Absolute phase in radians, in ``[0, 2*pi*f*(W-1)/W]``.

    Convention: pixel centres are at integer ``x_p``, the first pixel is ``x_p = 0`` with phase 0.
    """
    width, height = check_projector_size(projector_size)
    frequency = _positive_float(frequency, "frequency")
    axis = _axis(axis)
    extent = width if axis == "x" else height
    phase_1d = 2.0 * np.pi * frequency * np.arange(extent, dtype=np.float64) / extent
    if axis == "x":
        return np.broadcast_to(phase_1d[None, :], (height, width)).copy()  # (H, W)
    return np.broadcast_to(phase_1d[:, None], (height, width)).copy()  # (H, W)


def fringe_patterns(
    *,
    frequency=None,
    period=None,
    steps,
    projector_size,
    axis="x",
    offset=0.5,
    amplitude=0.45,
    bit_depth=8,
    shift_sign=-1,
    phase_offset=0.0,
    dtype=None,
) -> np.ndarray:
    """An ``N``-step phase-shifted fringe sequence for the projector (Eq. (1) of the paper).

    Parameters
    ----------
    frequency : float, optional
        Fringe periods across the extent along the fringe axis, > 0 (may be rational, e.g. 10.9).
        Give exactly one of ``frequency`` and ``period``.
    period : float, optional
        Fringe period in projector pixels, > 0; ``f = extent / period``.
    steps : int
        Number of phase steps ``N >= 3``.
    projector_size : (int, int)
        Projector ``(width, height)`` in pixels.
    axis : {"x", "y"}
        Fringe axis (see :func:`projector_phase`).
    offset, amplitude : float
        Level ``offset + amplitude*cos(.)`` as a fraction of full scale; the level must stay in
        ``[0, 1]``, i.e. ``amplitude >= 0`` and ``0 <= offset - amplitude``,
        ``offset + amplitude <= 1``.
    bit_depth : {8, 16}
        Projector bit depth; full scale is ``2**bit_depth - 1``.
    shift_sign : {-1, +1}
        Sign of the phase shift; -1 is the paper's Eq. (1).
    phase_offset : float
        Constant phase added to every image, radians.
    dtype : None or float dtype
        ``None`` (default): levels rounded to the nearest integer, ``uint8`` for ``bit_depth=8``,
        ``uint16`` for 16. A float dtype (e.g. ``float``): the unrounded levels in the same digital
        units ``[0, 2**bit_depth - 1]``, useful for tests and simulation.

    Returns
    -------
    ndarray (N, H, W)
        ``I_n = round((2**bit_depth - 1) * (offset + amplitude*cos(phi + phase_offset
        + shift_sign*2*pi*n/N)))`` for ``n = 0..N-1``.

    Convention: image ``n`` is 0-based and the phase ``phi`` increases with the projector column
    (``axis="x"``) or row (``axis="y"``), starting at 0 on the first pixel.
    """
    if (frequency is None) == (period is None):
        raise ValueError(
            "give exactly one of frequency and period; got "
            f"frequency={frequency!r}, period={period!r}"
        )
    width, height = check_projector_size(projector_size)
    axis = _axis(axis)
    steps = _steps(steps)
    if bit_depth not in _BIT_DEPTHS:
        raise ValueError(f"bit_depth must be one of {_BIT_DEPTHS}; got {bit_depth!r}")
    if shift_sign not in (-1, 1):
        raise ValueError(f"shift_sign must be -1 or +1; got {shift_sign!r}")
    offset = _finite_float(offset, "offset")
    amplitude = _finite_float(amplitude, "amplitude")
    phase_offset = _finite_float(phase_offset, "phase_offset")
    if amplitude < 0 or offset - amplitude < 0 or offset + amplitude > 1:
        raise ValueError(
            "offset +- amplitude must stay within [0, 1] of full scale with amplitude >= 0; "
            f"got offset={offset}, amplitude={amplitude} "
            f"(range [{offset - amplitude}, {offset + amplitude}])"
        )
    if dtype is not None and not np.issubdtype(np.dtype(dtype), np.floating):
        raise ValueError(f"dtype must be None or a float dtype; got {np.dtype(dtype)}")

    extent = width if axis == "x" else height
    if period is not None:
        frequency = frequency_from_period(period, extent)
    phase = projector_phase((width, height), frequency, axis=axis)  # (H, W)

    full_scale = float(2**bit_depth - 1)
    shifts = shift_sign * 2.0 * np.pi * np.arange(steps) / steps  # (N,)
    argument = phase[None, :, :] + phase_offset + shifts[:, None, None]  # (N, H, W)
    levels = full_scale * (offset + amplitude * np.cos(argument))  # (N, H, W)
    if dtype is not None:
        return levels.astype(dtype, copy=False)
    integer_dtype = np.uint8 if bit_depth == 8 else np.uint16
    return np.clip(np.rint(levels), 0.0, full_scale).astype(integer_dtype)


def _positive_float(value, name) -> float:
    value = _finite_float(value, name)
    if value <= 0:
        raise ValueError(f"{name} must be > 0; got {value}")
    return value


def _finite_float(value, name) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number; got {value!r}")
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite; got {value}")
    return value


def _axis(axis) -> str:
    if axis not in _AXES:
        raise ValueError(f"axis must be 'x' or 'y'; got {axis!r}")
    return axis


def _steps(steps) -> int:
    if isinstance(steps, bool) or not isinstance(steps, numbers.Integral) or steps < 3:
        raise ValueError(f"steps must be an integer >= 3; got {steps!r}")
    return int(steps)
