"""The number-theoretic (NT) prior of DP-TPU in the network's multi-frequency (MF) representation (no torch).

Why: NT's lookup (Eqs. (8)-(9)) decides the pair ``(k_h, k_l)`` from one pixel's key, and with the paper's
``f_l = 10.9`` some high frequencies are nearly degenerate pairs: for ``f_h = 60`` the ratio ``f_h / f_l`` is
5.5046, so ``k_l`` and ``k_l + 2`` predict high phases 0.009 periods apart (``f_h = 40``: ``k_l + 3``, 0.009;
76: ``k_l + 1``, 0.028; 80: ``k_l + 3``, 0.018). One pixel's noise (0.02-0.04 periods at the paper's 1 and 2
sigma) cannot tell them apart: the classical NT order is right on 21 % (1 sigma) and 14 % (2 sigma) of the
unseen rig's pixels at ``f_h = 60`` (docs/model-eval.md). As the network's coarse order, such a map carries
no information, and a 3x3 or 7x7 vote of it cannot recover it.

What does: ``k_l`` is one integer over a whole band of the surface between two wraps of ``psi_l`` (a period
of 10.9 across the projector is 30-60 camera pixels wide), so the evidence of every pixel of the band adds up:

1. **Bands** (:func:`low_order_bands`): 4-connected pixels whose low phase runs on without a wrap (a raw step
   of more than pi) or a jump (a wrapped step of more than :data:`BAND_JUMP_RAD`, a depth edge); pixels on a
   cut are left out. A depth edge that shifts the low phase by a whole period leaves it running on; there the
   band's residual ``b_p`` (below) takes a second value, and the pixels of that value become bands of their own:
   those whose local mean residual lies farther from the band's than half the turn between neighbouring low
   orders (:func:`merge_tolerance_rad`; 0.23 rad for ``88 / 10.9``, whose orders ``m`` and ``m + 1`` give
   residuals only 0.073 periods apart). Mixed pixels, which integrate both surfaces, smooth such an edge's low
   phase into steps below :data:`BAND_JUMP_RAD`, so on a real camera this is the common case.
2. **Band order**: for a band ``B`` and a candidate low order ``m``, Eq. (3) for both frequencies at one
   projector column says ``(f_h / f_l) (m + psi_l / 2pi) - psi_h / 2pi`` is an integer (``k_h``). Its
   circular agreement over the band, ``sum_B cos(2pi ((f_h/f_l) m + b_p))`` with ``b_p = (f_h/f_l) psi_l/2pi -
   psi_h/2pi``, equals ``Re(exp(2pi i (f_h/f_l) m) Z_B)``, ``Z_B = sum_B exp(2pi i b_p)``: two sums a band, then
   one complex product for each of the ``ceil(f_l)`` candidates. The best ``m`` is the band's order (the last
   one only for a band that stays on the projector: with f_l = 10.9 the projector ends at 0.9 of that
   period). Bands of fewer than :data:`MIN_BAND_PIXELS` keep the pixel's own NT ``k_l``.
3. **Cut pixels and small bands** take the neighbour vote of :func:`dptpu.models.consensus.consensus_order`
   on the low absolute phase.

The network then sees NT as it sees MF (:func:`mf_representation`): the low absolute phase expressed at one
period across the projector, ``Psi_1 = 2pi (k_l + psi_l / 2pi) / f_l`` (the MF low phase of ``f_l = 1``, with
``f_l`` times less noise), and the MF order of Eq. (5) from it, ``k_h = Round((f_h Psi_1 - psi_h) / 2pi)``.
Measured on the unseen rig (320x240, 21 frequencies): the band order alone makes the MF-equivalent order right
on 99.86 % / 99.49 % of pixels at 1 / 2 sigma (mean over f_h; classical NT 65.65 % / 49.21 %); the network and
the consensus on top, 99.89 % / 99.69 % (docs/model-eval.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .consensus import consensus_order

__all__ = ["BAND_JUMP_RAD", "MIN_BAND_PIXELS", "NTInputs", "low_order_bands", "low_order_from_high",
           "merge_tolerance_rad", "mf_representation"]

#: A wrapped step of the low phase larger than this between 4-neighbours cuts a band (a depth edge), radians.
#: The low phase of ``f_l = 10.9`` changes 0.1-0.3 rad a pixel on the rigs of this project; its noise is
#: 0.02-0.04 rad at the paper's 1 and 2 sigma.
BAND_JUMP_RAD = 0.5
#: A band pixel whose 3x3 mean residual ``b`` lies farther than this from its band's (radians) belongs to another
#: surface that the band ran into (:func:`_merged_pixels`).
MERGE_TOLERANCE_RAD = 0.3 * np.pi
#: Side of the window (pixels) whose circular mean residual :func:`_merged_pixels` compares with its band's when the
#: tolerance is below :data:`MERGE_TOLERANCE_RAD` (:func:`merge_tolerance_rad`): 25 pixels average the noise of the
#: paper's 3-step, 2 sigma inputs (0.3-0.4 rad a pixel for ``f_h/f_l`` near 8) to below a third of a 0.23 rad
#: tolerance; 3x3 does not (measured on the outside rigs of sim/outside_rigs.py, docs/model-eval.md).
MERGE_WINDOW = 5
#: The smallest split tolerance (radians) the window's mean resolves: the 5x5 mean of the residual's noise at the
#: paper's 3-step, 2 sigma inputs is 0.06-0.08 rad for ``f_h/f_l`` near 8, so a tolerance below twice that splits
#: bands on noise. Pairs whose neighbouring low orders lie closer (``76 / 10.9``: half-turn 0.086 rad; ``44 / 10.9``:
#: 0.115) keep :data:`MERGE_TOLERANCE_RAD`: their edges cannot be told from noise by the residual (on the unseen rig,
#: 320x240, 2 sigma, the half-turn tolerance gave 85.29 % at ``f_h = 76``).
MIN_SPLIT_TOLERANCE_RAD = 0.15
#: Passes of the split (:func:`_bands`) against a tolerance below :data:`MERGE_TOLERANCE_RAD`: the first splits off
#: the other surface's pixels whose window lies mostly on it, the second, measuring the pieces left, those next to
#: the edge (one pass with the 0.3 pi tolerance).
MERGE_PASSES = 2
#: Bands smaller than this keep the per-pixel NT low order (and the vote), pixels.
MIN_BAND_PIXELS = 50
_TWO_PI = 2.0 * np.pi
# A band may take the last low order only if at most this share of its pixels would lie beyond the projector's
# end by more than the slack (periods of f_l): the band of that order holds only the first ceil(f_l) - f_l of a period.
_PROJECTOR_END_SHARE = 0.1
_PROJECTOR_END_SLACK = 0.02
# _band_modes: bins of the circular histogram of a band's local residuals.
_MODE_BINS = 128


def low_order_from_high(order_high, psi_h, psi_l, f_h: float, f_l: float) -> np.ndarray:
    """The low-frequency order ``k_l`` implied by a high-frequency order, ``(H, W)`` int32.

    Eq. (3) for both frequencies at one projector column: ``(k_l + psi_l/2pi) / f_l = (k_h + psi_h/2pi) / f_h``,
    so ``k_l = Round(f_l/f_h (k_h + psi_h/2pi) - psi_l/2pi)``. With NT's pair ``(k_h, k_l)`` from the lookup
    table this gives the table's ``k_l``.

    Parameters
    ----------
    order_high : ndarray (H, W) int
    psi_h, psi_l : ndarray (H, W)
        Wrapped phases, radians, finite.
    f_h, f_l : float
        Periods across the projector.
    """
    return np.rint(f_l / f_h * (order_high + psi_h / _TWO_PI) - psi_l / _TWO_PI).astype(np.int32)


def low_order_bands(psi_h, psi_l, f_h: float, f_l: float, valid, order_low, *,
                    jump_rad: float = BAND_JUMP_RAD, min_pixels: int = MIN_BAND_PIXELS):
    """Steps 1 and 2 of the module docstring: the band order of every band pixel (``psi_h`` enters step 2 only).

    Parameters
    ----------
    psi_h, psi_l : ndarray (H, W) float
        Wrapped phases of ``f_h`` and ``f_l``, radians, finite where ``valid``.
    f_h, f_l : float
        Periods across the projector (``f_l`` need not be an integer: the paper's 10.9).
    valid : ndarray (H, W) bool
    order_low : ndarray (H, W) int
        Per-pixel low order (NT's ``k_l``), kept outside the bands.

    Returns
    -------
    order : ndarray (H, W) int32
        The band's order on band pixels, ``order_low`` elsewhere.
    banded : ndarray (H, W) bool
        Pixels of a band of at least ``min_pixels``.
    """
    valid = np.asarray(valid, dtype=bool)
    psi_l = np.where(valid, psi_l, 0.0)
    psi_h = np.where(valid, psi_h, 0.0)
    ratio = f_h / f_l
    core = _band_pixels(psi_l, valid, jump_rad)
    residual = np.where(core, ratio * psi_l - psi_h, 0.0)  # 2pi b_p, (H, W)
    labels, count = _bands(core, residual, ratio, int(np.ceil(f_l)))
    band = labels[core]  # (P,) band of every core pixel; 0 is the background
    z_re, z_im, size = _band_sums(residual, core, band, count)
    candidates = np.arange(int(np.ceil(f_l)))  # (M,)
    turn = _TWO_PI * ratio * candidates  # (M,)
    agreement = np.cos(turn)[None, :] * z_re[:, None] - np.sin(turn)[None, :] * z_im[:, None]  # (count, M)
    last = candidates[-1]  # the projector ends inside the last low period (f_l = 10.9: at 0.9 of it)
    beyond = np.bincount(band, (last + psi_l[core] / _TWO_PI) > f_l + _PROJECTOR_END_SLACK, minlength=count)
    agreement[beyond > _PROJECTOR_END_SHARE * np.maximum(size, 1), -1] = -np.inf
    best = np.argmax(agreement, axis=1).astype(np.int32)  # (count,)
    large = size >= int(min_pixels)
    large[0] = False
    banded = large[labels] & core
    order = np.where(banded, best[labels], order_low).astype(np.int32)
    return order, banded


def _band_pixels(psi_l, valid, jump_rad: float) -> np.ndarray:
    """Valid pixels on no cut (step 1): no wrap or jump of the low phase to any valid 4-neighbour, ``(H, W)`` bool."""
    core = valid.copy()
    for axis in (0, 1):
        step = np.diff(psi_l, axis=axis)
        wrapped = (step + np.pi) % _TWO_PI - np.pi
        both = np.logical_and(np.delete(valid, 0, axis=axis), np.delete(valid, -1, axis=axis))
        cut = (np.abs(step) > np.pi) | (np.abs(wrapped) > jump_rad) | ~both  # (H-1, W) or (H, W-1)
        if axis == 0:
            core[1:] &= ~cut
            core[:-1] &= ~cut
        else:
            core[:, 1:] &= ~cut
            core[:, :-1] &= ~cut
    return core


def merge_tolerance_rad(ratio: float, orders: int) -> float:
    """How far (radians) a band pixel's local mean residual may lie from its band's before it counts as another
    surface's (:func:`_bands`): :data:`MERGE_TOLERANCE_RAD`, or half the turn between neighbouring low orders where
    that is smaller, unless that is below :data:`MIN_SPLIT_TOLERANCE_RAD` (then the cap again).

    Neighbouring low orders ``m`` and ``m + 1`` give residuals ``2pi (f_h/f_l)`` apart (modulo ``2pi``): 0.46 rad
    for ``88 / 10.9`` (``f_h/f_l = 8.073``). A depth edge whose mixed pixels carry the low phase on with a shift of
    one period joins two surfaces of neighbouring orders in one band; a tolerance above half that turn would keep
    them together and give the smaller one the other's order (every pixel ``f_h/f_l`` high orders off).
    """
    if orders < 2:
        return MERGE_TOLERANCE_RAD
    turn = (ratio % 1.0) * _TWO_PI
    half_turn = 0.5 * min(turn, _TWO_PI - turn)
    if half_turn < MIN_SPLIT_TOLERANCE_RAD:  # closer than noise lets a window tell apart: the cap
        return MERGE_TOLERANCE_RAD
    return float(min(MERGE_TOLERANCE_RAD, half_turn))


def _bands(core, residual, ratio: float, orders: int) -> tuple[np.ndarray, int]:
    """Band labels ``(H, W)`` int32 (0 off the bands) and their count (with 0): the 4-connected components of
    ``core``, where a band that ran over a depth edge (:func:`_merged_pixels`) gives the other surface's pixels
    bands of their own (:data:`MERGE_PASSES` times)."""
    tolerance_rad = merge_tolerance_rad(ratio, orders)
    count, labels = cv2.connectedComponents(core.astype(np.uint8), connectivity=4, ltype=cv2.CV_32S)
    for _ in range(MERGE_PASSES if tolerance_rad < MERGE_TOLERANCE_RAD else 1):
        outliers = _merged_pixels(residual, core, labels, count, tolerance_rad)
        if not outliers.any():
            break
        count_in, labels_in = _split_components(labels * ~outliers, count)
        count_out, labels_out = _split_components(labels * outliers, count)  # never joins two bands' outliers
        labels = np.where(outliers, labels_out + (count_in - 1), labels_in).astype(np.int32)
        labels[~core] = 0
        count = count_in + count_out - 1
    return labels, count


def _split_components(labels, count) -> tuple[int, np.ndarray]:
    """The 4-connected pieces of every band of ``labels`` (``(H, W)``, 0 = off the bands, ``count`` labels with 0):
    their count (with 0) and labels ``1..``, ``(H, W)`` int32. Pieces of two bands that touch stay apart."""
    out = np.zeros(labels.shape, np.int32)
    on = labels > 0
    _, components = cv2.connectedComponents(on.astype(np.uint8), connectivity=4, ltype=cv2.CV_32S)
    pair = components[on].astype(np.int64) * (int(count) + 1) + labels[on]  # (P,) a piece: component and band
    unique, inverse = np.unique(pair, return_inverse=True)
    out[on] = inverse.astype(np.int32) + 1
    return unique.size + 1, out


def _band_sums(residual, core, band, count):
    """``Re Z_B``, ``Im Z_B`` and the pixel count of every band, ``(count,)`` each."""
    z_re = np.bincount(band, np.cos(residual[core]), minlength=count)
    z_im = np.bincount(band, np.sin(residual[core]), minlength=count)
    return z_re, z_im, np.bincount(band, minlength=count)


def _merged_pixels(residual, core, labels, count, tolerance_rad: float) -> np.ndarray:
    """Band pixels whose local circular mean residual lies more than ``tolerance_rad`` from their band's value,
    ``(H, W)`` bool: a 3x3 mean against :data:`MERGE_TOLERANCE_RAD` (0.15 periods), a :data:`MERGE_WINDOW` square
    one against a smaller tolerance (:func:`merge_tolerance_rad`).

    On one surface ``b_p`` is one value (``-(f_h/f_l) k_l`` modulo 1) but for noise; a band that runs over a
    depth edge where the low phase runs on (a shift of a whole low period) holds a second value, ``f_h/f_l``
    times the order step apart modulo 1 (half a period for f_h = 60). Against the smaller tolerance the band's
    value is its most common local value (:func:`_band_modes`), not its mean, which the second surface would pull
    towards itself by a good part of that tolerance (or, at ``f_h/f_l = 8.807``, onto a third order's value).
    """
    band = labels[core]
    narrow = tolerance_rad < MERGE_TOLERANCE_RAD
    window = (MERGE_WINDOW, MERGE_WINDOW) if narrow else (3, 3)
    weight = core.astype(np.float64)
    local_re = cv2.boxFilter(np.cos(residual) * weight, -1, window, normalize=False)
    local_im = cv2.boxFilter(np.sin(residual) * weight, -1, window, normalize=False)
    local = np.arctan2(local_im, local_re)  # (H, W) radians
    if narrow:  # the band's most common local value: its mean would lie between two surfaces' values
        band_angle = _band_modes(local[core], band, count, tolerance_rad)
    else:  # orders far apart (3x3 against the band's mean)
        z_re, z_im, _ = _band_sums(residual, core, band, count)
        band_angle = np.arctan2(z_im, z_re)
    deviation = local - band_angle[labels]
    deviation = np.abs((deviation + np.pi) % _TWO_PI - np.pi)
    return core & (deviation > tolerance_rad)


def _band_modes(angle, band, count, tolerance_rad: float) -> np.ndarray:
    """The most common value of ``angle`` (``(P,)`` radians) in each band (``band``: ``(P,)`` labels < ``count``),
    ``(count,)`` radians: the centre of the ``2 * tolerance_rad`` arc that holds the most of the band's values."""
    bins = _MODE_BINS
    index = np.floor((angle + np.pi) / _TWO_PI * bins).astype(np.int64) % bins  # (P,)
    histogram = np.bincount(band * bins + index, minlength=count * bins).reshape(count, bins).astype(np.float64)
    half = max(1, int(tolerance_rad / _TWO_PI * bins))
    arcs = sum(np.roll(histogram, shift, axis=1) for shift in range(-half, half + 1))  # (count, bins)
    return (np.argmax(arcs, axis=1) + 0.5) * _TWO_PI / bins - np.pi


@dataclass(frozen=True, eq=False)
class NTInputs:
    """NT in the MF representation: the network's inputs and the classical order for its consensus.

    Attributes
    ----------
    wrapped_low : ndarray (H, W) float64
        ``Psi_1``, the low absolute phase at one period across the projector, radians (0 where not valid).
    coarse_order : ndarray (H, W) int32
        Eq. (5) with ``f_l = 1`` on ``Psi_1``: the MF order of ``f_h``.
    order_low : ndarray (H, W) int32
        The low order ``k_l`` after the bands and the vote.
    banded : ndarray (H, W) bool
        Pixels whose ``k_l`` came from a band.
    """

    wrapped_low: np.ndarray
    coarse_order: np.ndarray
    order_low: np.ndarray
    banded: np.ndarray


def mf_representation(psi_h, psi_l, order_nt, f_h: float, f_l: float, valid) -> NTInputs:
    """NT's inputs to the network in the MF representation (module docstring, steps 1-3 and ``Psi_1``).

    Parameters
    ----------
    psi_h, psi_l : ndarray (H, W)
        Wrapped phases of ``f_h`` and ``f_l`` (radians, ``[0, 2pi)``; NaN allowed where not ``valid``).
    order_nt : ndarray (H, W) int or float
        NT's high order ``k_h`` (Eq. (9)); NaN where the lookup rejected the key (the bands and the vote
        decide those pixels), anything where not ``valid``.
    f_h, f_l : float
        NT's frequencies, periods across the projector (``f_h > f_l > 0``).
    valid : ndarray (H, W) bool
        Pixels with finite phases.

    Returns
    -------
    NTInputs
    """
    psi_h = np.asarray(psi_h, dtype=np.float64)
    psi_l = np.asarray(psi_l, dtype=np.float64)
    order_nt = np.asarray(order_nt)
    valid = np.asarray(valid, dtype=bool)
    if psi_h.ndim != 2 or any(a.shape != psi_h.shape for a in (psi_l, order_nt, valid)):
        raise ValueError("mf_representation takes (H, W) maps of one shape; got psi_h, psi_l, order_nt, valid "
                         f"shapes {[np.shape(a) for a in (psi_h, psi_l, order_nt, valid)]}")
    if not (np.isfinite(f_h) and np.isfinite(f_l) and f_h > f_l > 0):
        raise ValueError(f"NT frequencies must satisfy f_h > f_l > 0; got f_h = {f_h!r}, f_l = {f_l!r}")
    valid = valid & np.isfinite(psi_h) & np.isfinite(psi_l)
    psi_h = np.where(valid, psi_h, 0.0)
    psi_l = np.where(valid, psi_l, 0.0)
    order_nt = np.where(valid & np.isfinite(order_nt), order_nt, 0)  # NT's rejected keys: the bands decide
    per_pixel = low_order_from_high(order_nt, psi_h, psi_l, f_h, f_l)
    banded_order, banded = low_order_bands(psi_h, psi_l, f_h, f_l, valid, per_pixel)
    order_low = consensus_order(banded_order, banded_order, psi_l, valid)  # step 3
    psi_1 = np.where(valid, (order_low + psi_l / _TWO_PI) * (_TWO_PI / f_l), 0.0)  # (H, W) radians
    coarse = np.where(valid, np.rint((f_h * psi_1 - psi_h) / _TWO_PI), 0).astype(np.int32)  # Eq. (5), f_l = 1
    return NTInputs(psi_1, coarse, order_low, banded)
