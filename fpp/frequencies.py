"""Frequencies of a fringe scan: when two are the same, and which ones a temporal unwrapping method uses.

One rule for every caller: the unwrap node (a scan's phase maps), :func:`dptpu.fpp.reconstruct.unwrap_capture`
(a capture folder's phase sequences), the node assembling a scan's frames and the sim node's source (the frames
asked for by frequency).

A frequency ``f`` is the number of fringe periods across the projector extent (``phi = 2*pi*f*x_p/W``); it may be
rational (``10.9``, ``1920/42``).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from .methods import PHASE_SEQUENCE_METHODS

__all__ = ["FREQUENCY_RELATIVE_TOLERANCE", "find_frequency", "same_frequency", "select_frequencies"]

#: Two frequencies within this relative difference are the same one (see :func:`same_frequency`).
FREQUENCY_RELATIVE_TOLERANCE = 1e-3
#: Slack on the bounds ``f_l <= 1`` (mf) and ``f_h - f_l <= 1`` (mw), for frequencies that round to them.
_BOUND_SLACK = 1e-9


def same_frequency(a: float, b: float) -> bool:
    """Whether two frequencies name the same one: ``|a - b| <= 1e-3 * max(|a|, |b|)``.

    The tolerance (:data:`FREQUENCY_RELATIVE_TOLERANCE`) sits between two bounds:

    - above how far one frequency drifts on its way between programs: a rational frequency such as ``10.9`` or
      ``1920/42`` is stored rounded, in float32 (a relative ``6e-8``: the wire's and the sim's frames), in float64
      (``1e-16``: YAML and msgpack floats), as a period in projector pixels that gives it back by a division, or
      typed with 4 to 6 significant digits (``--high 45.714`` for ``1920/42 = 45.7142857``: ``6e-6``;
      ``20.27`` for ``912/45 = 20.2667``: ``2e-4``; the ``%g`` of every message: at most ``5e-6``);
    - below the closest two frequencies that one scan can use together: a pair within ``1e-3`` of each other
      beats at ``f_h - f_l < f_h / 1000``, which multiplies the phase noise by more than 1000 in Eqs. (6)-(7)
      of the paper, so no method unwraps with such a pair, and on a projector of a few thousand pixels the two
      differ by less than one period anyway.
    """
    return abs(a - b) <= FREQUENCY_RELATIVE_TOLERANCE * max(abs(a), abs(b))


def find_frequency(frequencies: Sequence[float], value, *, option: str = "frequency", context: str = "") -> int:
    """Index of the one frequency of ``frequencies`` that is ``value`` (:func:`same_frequency`).

    Parameters
    ----------
    frequencies : sequence of float
        Periods across the projector extent.
    value : float
        The frequency asked for, > 0.
    option : str
        What the caller calls the choice (``--high``, ``high_frequency``), for the messages.
    context : str
        What the caller has, for the messages (``"the scan has frequencies 16, 1"``).

    Raises
    ------
    ValueError
        ``value`` is not a frequency > 0, no frequency is ``value`` ("unknown frequency"), or several are.
    """
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{option} must be a frequency (periods across the projector); got {value!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{option} must be a frequency > 0; got {value:g}")
    matches = [i for i, f in enumerate(frequencies) if same_frequency(float(f), value)]
    where = f"; {context}" if context else ""
    if not matches:
        raise ValueError(f"unknown frequency {value:g} ({option}){where}")
    if len(matches) > 1:
        raise ValueError(f"{len(matches)} frequencies are {value:g} ({option}){where}")
    return matches[0]


def select_frequencies(method: str, frequencies: Iterable[float], *, high=None, low=None,
                       options: tuple[str, str] = ("high", "low"), context: str | None = None) -> list[int]:
    """Indices into ``frequencies`` of the phase maps a method uses, the unwrapped (high) one first.

    Parameters
    ----------
    method : {"mf", "mw", "nt", "heterodyne"}
        One of :data:`dptpu.fpp.methods.PHASE_SEQUENCE_METHODS`.
    frequencies : iterable of float (a list, an ndarray)
        Frequencies of a scan's phase maps (periods across the projector extent), in any order.
    high, low : float, optional
        The frequencies to use (None: the default). ``high`` default: the highest. ``low`` default: for ``mf`` the
        lowest (it must be <= 1, Eq. (5)); for ``mw`` the one with ``0 < f_h - f_l <= 1`` farthest from ``f_h``
        (Eqs. (6)-(7)); for ``nt`` the only other one (Eqs. (8)-(9)). ``heterodyne`` unwraps with every frequency,
        highest first, and gives the highest (:func:`dptpu.fpp.tpu.unwrap_heterodyne`): it takes neither.
    options : (str, str)
        What the caller calls the two choices, for the messages: ``("--high", "--low")`` on the command line,
        ``("high_frequency", "low_frequency")`` for the unwrap node's parameters.
    context : str, optional
        What the caller has, for the messages (default ``"the scan has frequencies 16, 1"``).

    Returns
    -------
    list of int
        Two indices (mf, mw, nt: high, low) or all of them, highest first (heterodyne).

    Raises
    ------
    ValueError
        An unknown method; a requested frequency the scan lacks; a frequency the method uses that appears twice;
        a scan that lacks what the method needs. The message says what the scan has and what to change.
    """
    if method not in PHASE_SEQUENCE_METHODS:
        raise ValueError(f"unknown unwrapping method {method!r}; expected one of {', '.join(PHASE_SEQUENCE_METHODS)}")
    freqs = [float(f) for f in frequencies]
    if context is None:
        context = f"the scan has frequencies {', '.join(f'{f:g}' for f in freqs) or 'none'}"
    high_option, low_option = options
    if len(freqs) < 2:
        raise ValueError(f"{method} needs two or more frequencies; {context}")
    if method == "heterodyne":
        if high is not None or low is not None:
            raise ValueError(f"heterodyne unwraps with every frequency and gives the highest; {high_option} and "
                             f"{low_option} do not apply to it")
        chosen = sorted(range(len(freqs)), key=lambda i: -freqs[i])
        _check_distinct(method, freqs, chosen, context)
    else:
        h = (find_frequency(freqs, high, option=high_option, context=context) if high is not None
             else max(range(len(freqs)), key=lambda i: freqs[i]))
        _check_distinct(method, freqs, [h], context)
        if low is not None:
            low_index = find_frequency(freqs, low, option=low_option, context=context)
            if low_index == h:
                raise ValueError(f"{low_option} {float(low):g} is the high frequency {freqs[h]:g}; the low one must "
                                 f"be another")
        else:
            low_index = _default_low(method, freqs, h, low_option, context)
        chosen = [h, low_index]
        _check_distinct(method, freqs, [low_index], context)
    return chosen


def _check_distinct(method: str, freqs: list[float], indices, context: str) -> None:
    """ValueError when a frequency the method uses appears more than once."""
    for i in indices:
        count = sum(same_frequency(freqs[i], f) for f in freqs)
        if count > 1:
            raise ValueError(f"frequency {freqs[i]:g} appears {count} times; {method} needs the frequencies it uses "
                             f"to be distinct ({context})")


def _default_low(method: str, freqs: list[float], h: int, low_option: str, context: str) -> int:
    """The default low frequency of a two-frequency method (see :func:`select_frequencies`)."""
    others = [i for i in range(len(freqs)) if i != h]
    if method == "mf":
        lowest = min(others, key=lambda i: freqs[i])
        if freqs[lowest] > 1.0 + _BOUND_SLACK:
            raise ValueError(f"mf needs a low frequency <= 1 (one fringe across the projector, Eq. (5)); {context}: "
                             "use heterodyne or nt")
        return lowest
    if method == "mw":
        candidates = [i for i in others if 0 < freqs[h] - freqs[i] <= 1.0 + _BOUND_SLACK]
        if not candidates:
            raise ValueError(f"mw needs a low frequency with 0 < f_h - f_l <= 1 for f_h = {freqs[h]:g}; {context}: "
                             f"choose it with {low_option}, or use another method")
        return max(candidates, key=lambda i: freqs[h] - freqs[i])
    if len(others) != 1:  # nt
        raise ValueError(f"nt takes the one other frequency by default, but {context}: choose the low one with "
                         f"{low_option}")
    return others[0]
