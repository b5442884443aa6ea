"""Temporal phase unwrapping (TPU): multi-frequency, multi-wavelength, heterodyne and number-theoretic.

Every method turns the wrapped phase ``psi_h`` of a high-frequency fringe sequence into the absolute
phase ``Psi_h = psi_h + 2*pi*k_h`` (Eq. (3) of the paper) by finding the fringe order ``k_h`` of each
pixel from one or more lower-frequency wrapped phases:

- ``unwrap_mf``: multi-frequency (MF), Eq. (5); needs ``f_l <= 1`` (so ``k_l = 0``). ``unwrap_mf_float32``:
  the same in float32, for float32 maps (the unwrap node).
- ``unwrap_with_reference``: Eq. (5) against an already absolute ``Psi_l`` of any ``f_l``.
- ``unwrap_mw``: multi-wavelength (MW), Eqs. (6)-(7); needs ``0 < f_h - f_l <= 1``.
- ``unwrap_heterodyne``: Eqs. (6)-(7) as a beat tree over 2 or more frequencies; needs the final
  beat in ``(0, 1]``.
- ``unwrap_nt``: number-theoretic (NT), Eqs. (8)-(9): the measured key is matched to the nearest key
  of the fringe-order pairs that occur across the projector (:func:`nt_lookup_table`); needs
  ``LCM(lambda_h, lambda_l) >= extent``.
- ``unwrap``: the two-frequency methods by name (``"mf"``, ``"mw"``, ``"nt"``).

Convention: wrapped phases lie in ``[0, 2*pi)`` and the absolute phase of projector coordinate
``x_p`` (0-based, centre of the first projector pixel is 0) at frequency ``f`` is
``phi = 2*pi*f*x_p/W``, so the fringe order is ``k = floor(phi / (2*pi))`` and ``phi = psi + 2*pi*k``.
A phase in ``(-pi, pi]`` (raw ``arctan2``) must be mapped with ``np.mod(psi, 2*pi)`` first.

Every method returns an :class:`Unwrapped`; its ``reliability`` is ``1 - 2*|q - Round(q)|`` of the
real quantity ``q`` that the method rounds (1 = ``q`` is exactly an integer, 0 = exactly half way
between two integers), a per-pixel margin against phase noise (NT: the key's distance to its decision
boundary over the table's tolerance, see :func:`unwrap_nt`).

References
----------
DP-TPU paper, section "Temporal phase unwrapping", Eqs. (3)-(9) (``shared/seed/dp-tpu-paper.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from itertools import pairwise

import numpy as np

from .methods import TWO_FREQUENCY_METHODS

__all__ = [
    "NTLookupTable",
    "Unwrapped",
    "nt_lookup_table",
    "nt_period_pair",
    "unwrap",
    "unwrap_heterodyne",
    "unwrap_mf",
    "unwrap_mf_float32",
    "unwrap_mw",
    "unwrap_nt",
    "unwrap_with_reference",
]

TWO_PI = 2.0 * np.pi

# A wrapped phase may exceed [0, 2*pi) by this much (radians) through float rounding of np.mod.
_WRAP_TOLERANCE_RAD = 1e-6
# nt_period_pair: frequencies must be within this relative distance of a fraction whose
# denominator is at most _MAX_DENOMINATOR.
_MAX_DENOMINATOR = 1000
_RATIONAL_RELATIVE_TOLERANCE = 1e-9
# nt_lookup_table: projector segments shorter than this fraction of the extent are coincident breakpoints,
# and keys closer than it are equal (an ambiguous pair).
_NT_SEGMENT_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class Unwrapped:
    """Result of temporal phase unwrapping for the highest frequency.

    Attributes
    ----------
    fringe_order : ndarray of int32, shape (H, W)
        Fringe order ``k_h`` of every pixel; 0 at invalid pixels.
    absolute_phase : ndarray of float64, shape (H, W)
        Absolute phase ``Psi_h = psi_h + 2*pi*k_h`` in radians (Eq. (3) of the paper), in
        ``[0, 2*pi*f_h)`` for a correct order; NaN at invalid pixels.
    valid : ndarray of bool, shape (H, W)
        True where the pixel was unwrapped: its inputs were finite (and marked valid by the caller's
        mask, if any) and, for NT, its lookup key was in the table.
    reliability : ndarray of float64, shape (H, W)
        ``1 - 2*|q - Round(q)|`` in ``[0, 1]`` of the quantity ``q`` that was rounded to an integer
        (MF/MW: the fringe order of Eqs. (5)/(7); heterodyne: the minimum over the levels of the
        beat tree). 1 means ``q`` was exactly an integer, 0 exactly half way between two. NT: the
        key's distance to the nearest decision boundary of its table entry over the table's
        ``tolerance_px``, clipped to ``[0, 1]`` (0 = on a boundary). 0 at invalid pixels.
    n_rejected : int
        Pixels that were valid on input but that the method rejected (NT: key outside every table
        entry's decision cell, nearer to a fringe-order pair that cannot occur on the projector than to
        the smallest or largest key); 0 for the other methods.

    Notes
    -----
    ``eq=False``: instances compare by identity (comparing arrays element-wise has no single truth
    value).
    """

    fringe_order: np.ndarray
    absolute_phase: np.ndarray
    valid: np.ndarray
    reliability: np.ndarray
    n_rejected: int = 0


@dataclass(frozen=True, eq=False)
class NTLookupTable:
    """Lookup table of Eq. (9): the key of every fringe-order pair that occurs across the projector.

    A projector coordinate ``x_p`` in ``[0, W)`` has orders ``k_h = floor(x_p/lambda_h)`` and
    ``k_l = floor(x_p/lambda_l)``; its key is ``lambda_h*k_h - lambda_l*k_l`` projector pixels, the
    value that the measured key ``(lambda_l*psi_l - lambda_h*psi_h)/(2*pi)`` takes without noise.

    Attributes
    ----------
    key_px : ndarray of float64, shape (M,)
        Keys of the occurring pairs in projector pixels, sorted ascending, distinct.
    k_h, k_l : ndarray of int32, shape (M,)
        Fringe orders of the pair with key ``key_px[i]``.
    lambda_h_px, lambda_l_px : float
        Periods ``W/f_h`` and ``W/f_l`` in projector pixels.
    tolerance_px : float
        Half the smallest gap between neighbouring keys, pixels: a key error below it never changes
        the matched pair (see :attr:`tolerance_rad`).
    outside_low_px, outside_high_px : float
        The nearest keys below the smallest and above the largest key of pairs that cannot occur on the
        projector (``k_l`` in ``[0, ceil(f_l))``, any ``k_h``), pixels: the outer decision boundaries
        lie half way to them, so that a key is matched to the pair an exhaustive search over ``k_l``
        finds. NaN (the default): half the adjacent gap outside the first and last key.
    """

    key_px: np.ndarray
    k_h: np.ndarray
    k_l: np.ndarray
    lambda_h_px: float
    lambda_l_px: float
    tolerance_px: float
    outside_low_px: float = float("nan")
    outside_high_px: float = float("nan")

    @property
    def tolerance_rad(self) -> float:
        """Largest phase error (radians) on both ``psi_h`` and ``psi_l`` that never changes the pair.

        A phase error ``d_h``, ``d_l`` moves the key by ``(lambda_l*d_l - lambda_h*d_h)/(2*pi)``
        pixels; with ``|d_h|, |d_l| < d`` that is below ``tolerance_px`` while
        ``d < 2*pi*tolerance_px / (lambda_h + lambda_l)``.
        """
        return TWO_PI * self.tolerance_px / (self.lambda_h_px + self.lambda_l_px)

    def match(self, key_px):
        """Nearest table entry of measured keys (any shape), vectorized.

        Parameters
        ----------
        key_px : ndarray of float, any shape
            Measured keys in projector pixels.

        Returns
        -------
        index : ndarray of int64, same shape
            Index of the nearest entry of :attr:`key_px`.
        margin_px : ndarray of float64, same shape
            Signed distance (pixels) from the key to the nearest decision boundary of its entry
            (the midpoints to the neighbouring keys; beyond the first and last key the midpoint to
            :attr:`outside_low_px` / :attr:`outside_high_px`). Negative outside every entry's cell.
        """
        key_px = np.asarray(key_px, dtype=np.float64)
        low_edge, high_edge = self._cell_edges
        index = np.searchsorted(low_edge[1:], key_px, side="right")  # low_edge[index] <= key < high_edge[index]
        margin_px = np.minimum(key_px - low_edge[index], high_edge[index] - key_px)
        return index, margin_px

    @property
    def _cell_edges(self):
        """(M,) lower and upper decision boundaries of each entry, pixels."""
        keys = self.key_px
        mid = 0.5 * (keys[:-1] + keys[1:])
        below = self.outside_low_px if math.isfinite(self.outside_low_px) else keys[0] - (keys[1] - keys[0])
        above = self.outside_high_px if math.isfinite(self.outside_high_px) else keys[-1] + (keys[-1] - keys[-2])
        low = np.concatenate([[0.5 * (keys[0] + below)], mid])
        high = np.concatenate([mid, [0.5 * (keys[-1] + above)]])
        return low, high


# --------------------------------------------------------------------------------------------
# Methods
# --------------------------------------------------------------------------------------------


def unwrap_mf(psi_h, psi_l, f_h, f_l=1.0, *, valid=None) -> Unwrapped:
    """Multi-frequency (MF) temporal phase unwrapping, Eq. (5) of the paper.

    Parameters
    ----------
    psi_h : ndarray, shape (H, W)
        Wrapped phase of the high frequency in radians, ``[0, 2*pi)``; NaN marks an invalid pixel.
    psi_l : ndarray, shape (H, W)
        Wrapped phase of the low frequency in radians, ``[0, 2*pi)``; NaN marks an invalid pixel.
    f_h : float
        High frequency, periods across the projector extent, > 0.
    f_l : float, optional
        Low frequency, ``0 < f_l <= 1`` so that its wrapped phase is already absolute
        (``k_l = 0``; the paper uses ``f_l = 1``). For ``f_l > 1`` unwrap the low phase first and
        call :func:`unwrap_with_reference`.
    valid : ndarray of bool, shape (H, W), optional
        Pixels to unwrap; inputs must be finite where it is True.

    Returns
    -------
    Unwrapped
        Fringe order, absolute phase, validity and reliability of the high frequency.

    Notes
    -----
    ``k_h = Round[(f_h*Psi_l - f_l*psi_h) / (2*pi*f_l)]`` with ``Psi_l = psi_l``. A phase error
    ``d_h``, ``d_l`` moves the rounded quantity by ``(r*d_l - d_h)/(2*pi)``, ``r = f_h/f_l``, so the
    order is right while ``|r*d_l - d_h| < pi``.
    """
    f_h, f_l = _check_mf_frequencies(f_h, f_l)
    psi_h = _as_phase_map("psi_h", psi_h, wrapped=True)
    psi_l = _as_phase_map("psi_l", psi_l, wrapped=True)
    mask = _pixel_mask({"psi_h": psi_h, "psi_l": psi_l}, valid)
    return _unwrap_on_mask(_fill(psi_h, mask), _fill(psi_l, mask), f_h, f_l, mask)


def unwrap_mf_float32(psi_h, psi_l, f_h, f_l=1.0, *, valid=None) -> Unwrapped:
    """Multi-frequency (MF) unwrapping, Eq. (5), computed in float32: :func:`unwrap_mf` for float32 phase maps.

    Parameters and checks as :func:`unwrap_mf` (the same ``ValueError`` messages); ``psi_h`` and ``psi_l`` are
    taken as float32 (a float32 map is read, not copied).

    Returns
    -------
    Unwrapped
        ``fringe_order`` (H, W) int32, ``absolute_phase`` and ``reliability`` (H, W) **float32**, ``valid``.

    Notes
    -----
    ``q = (f_h/f_l * psi_l - psi_h) / (2*pi)`` in float32 is within ``ulp(2*pi*r) / (4*pi) + 1.5 ulp(r)`` of
    the float64 ``q`` of the same maps (``r = f_h/f_l``; 1.4e-5 for ``r = 64``, measured 7e-6), so the fringe
    order equals :func:`unwrap_mf`'s wherever the reliability ``1 - 2|q - k|`` exceeds twice that (2.8e-5 at
    ``r = 64``; an order that close to half way is a coin toss for the phase noise anyway, ~1e-2 rad = 0.1 of
    ``q`` at ``r = 64``) and the reliabilities differ by at most as much; the absolute phase ``psi_h +
    2*pi*k`` (Eq. (3)) is within 2 float32 ulps of the float64 result cast to float32 (3e-5 rad at ``2*pi*64``,
    4e-5 projector pixels of 912 at ``f_h = 64``). About a third of the passes of :func:`unwrap_mf`, each over
    half the bytes: what the unwrap node runs for ``mf``, whose maps arrive and leave as float32.
    """
    f_h, f_l = _check_mf_frequencies(f_h, f_l)
    psi_h = _as_phase_map("psi_h", psi_h, wrapped=True, dtype=np.float32)
    psi_l = _as_phase_map("psi_l", psi_l, wrapped=True, dtype=np.float32)
    mask = _pixel_mask({"psi_h": psi_h, "psi_l": psi_l}, valid)
    invalid = ~mask
    q = np.multiply(psi_l, np.float32(f_h / f_l))  # (H, W) float32; NaN where invalid
    q -= psi_h
    q *= np.float32(1.0 / TWO_PI)
    order = np.rint(q)  # (H, W) float32 k_h
    reliability = np.subtract(q, order, out=q)
    np.abs(reliability, out=reliability)
    reliability *= np.float32(-2.0)
    reliability += np.float32(1.0)
    np.maximum(reliability, np.float32(0.0), out=reliability)  # 1 - 2|q - k| in [0, 1]
    np.copyto(reliability, np.float32(0.0), where=invalid)
    np.copyto(order, np.float32(0.0), where=invalid)  # no NaN reaches the integer cast
    fringe_order = order.astype(np.int32)
    absolute = np.multiply(order, np.float32(TWO_PI), out=order)
    absolute += psi_h  # Eq. (3)
    np.copyto(absolute, np.float32(np.nan), where=invalid)
    return Unwrapped(fringe_order=fringe_order, absolute_phase=absolute, valid=mask, reliability=reliability)


def unwrap_with_reference(psi_h, Psi_l_abs, f_h, f_l, *, valid=None) -> Unwrapped:
    """Unwrap ``psi_h`` against an already absolute lower-frequency phase, Eq. (5) of the paper.

    Parameters
    ----------
    psi_h : ndarray, shape (H, W)
        Wrapped phase of frequency ``f_h`` in radians, ``[0, 2*pi)``; NaN marks an invalid pixel.
    Psi_l_abs : ndarray, shape (H, W)
        Absolute phase of frequency ``f_l`` in radians (any finite value, ``2*pi*f_l*x_p/W``);
        NaN marks an invalid pixel.
    f_h, f_l : float
        Frequencies in periods across the projector extent, > 0 (any ratio; the order is right while
        the noise of ``(f_h/f_l)*Psi_l_abs - psi_h`` stays below ``pi``).
    valid : ndarray of bool, shape (H, W), optional
        Pixels to unwrap; inputs must be finite where it is True.

    Returns
    -------
    Unwrapped
        Fringe order and absolute phase of frequency ``f_h``.

    Notes
    -----
    ``k_h = Round[(f_h*Psi_l - f_l*psi_h) / (2*pi*f_l)]``; the hierarchical methods call this once
    per level.
    """
    f_h = _check_frequency("f_h", f_h)
    f_l = _check_frequency("f_l", f_l)
    psi_h = _as_phase_map("psi_h", psi_h, wrapped=True)
    Psi_l_abs = _as_phase_map("Psi_l_abs", Psi_l_abs, wrapped=False)
    mask = _pixel_mask({"psi_h": psi_h, "Psi_l_abs": Psi_l_abs}, valid)
    return _unwrap_on_mask(_fill(psi_h, mask), _fill(Psi_l_abs, mask), f_h, f_l, mask)


def unwrap_mw(psi_h, psi_l, f_h, f_l, *, valid=None) -> Unwrapped:
    """Multi-wavelength (MW) temporal phase unwrapping, Eqs. (6)-(7) of the paper.

    Parameters
    ----------
    psi_h, psi_l : ndarray, shape (H, W)
        Wrapped phases of the high and low frequency in radians, ``[0, 2*pi)``; NaN marks an
        invalid pixel.
    f_h, f_l : float
        Frequencies in periods across the projector extent, > 0, with equivalent frequency
        ``f_eq = f_h - f_l`` in ``(0, 1]`` (the paper pairs ``f_l = f_h - 1``).
    valid : ndarray of bool, shape (H, W), optional
        Pixels to unwrap; inputs must be finite where it is True.

    Returns
    -------
    Unwrapped
        Fringe order and absolute phase of ``f_h``.

    Notes
    -----
    Equivalent phase ``psi_eq = mod(psi_h - psi_l, 2*pi)`` of ``f_eq = f_h - f_l`` (Eq. (6)) is
    absolute because ``f_eq <= 1``; then
    ``k_h = Round[(f_h*psi_eq - f_eq*psi_h) / (2*pi*f_eq)]`` (Eq. (7)).
    """
    f_h = _check_frequency("f_h", f_h)
    f_l = _check_frequency("f_l", f_l)
    f_eq = _check_equivalent_frequency(f_h, f_l)
    psi_h = _as_phase_map("psi_h", psi_h, wrapped=True)
    psi_l = _as_phase_map("psi_l", psi_l, wrapped=True)
    mask = _pixel_mask({"psi_h": psi_h, "psi_l": psi_l}, valid)
    psi_h = _fill(psi_h, mask)
    psi_eq = _mod_two_pi(psi_h - _fill(psi_l, mask))  # Eq. (6), (H, W)
    return _unwrap_on_mask(psi_h, psi_eq, f_h, f_eq, mask)


def unwrap_heterodyne(phases, frequencies, *, valid=None) -> Unwrapped:
    """Hierarchical multi-wavelength (heterodyne) unwrapping of two or more frequencies.

    Parameters
    ----------
    phases : sequence of ndarray, each shape (H, W)
        Wrapped phases in radians, ``[0, 2*pi)``, one per frequency; NaN marks an invalid pixel.
    frequencies : sequence of float
        Frequencies in periods across the projector extent, > 0, distinct, in any order: they are
        sorted highest first internally (with their phases), and the result is for the highest.
        Example, CFPE's projector periods 42, 45, 48 px over 1920 px:
        ``[1920/42, 1920/45, 1920/48]``.
    valid : ndarray of bool, shape (H, W), optional
        Pixels to unwrap; inputs must be finite where it is True.

    Returns
    -------
    Unwrapped
        Fringe order and absolute phase of the highest frequency; ``reliability`` is the minimum
        over the levels of the beat tree.

    Notes
    -----
    Beat tree: level 0 holds the sorted frequencies ``f_1 > f_2 > ... > f_n``; each level beats
    neighbours, ``f_(i,i+1) = |f_i - f_(i+1)|`` with phase ``mod(+-(psi_i - psi_(i+1)), 2*pi)``
    (Eq. (6)), until one beat remains; it must lie in ``(0, 1]`` so its wrapped phase is absolute
    (for 42/45/48 px: ``f12 = 3.048``, ``f23 = 2.667``, ``f123 = 0.381``). Unwrapping then walks
    back down the first node of each level with the rounding of Eq. (5)/(7)
    (``f123 -> f12 -> f1``). Each level multiplies the phase noise by its frequency ratio.
    """
    phases = list(phases)
    frequencies = list(frequencies)
    if len(frequencies) < 2 or len(phases) != len(frequencies):
        raise ValueError(
            "unwrap_heterodyne needs 2 or more frequencies and one phase per frequency; got "
            f"{len(phases)} phases and {len(frequencies)} frequencies"
        )
    freqs = [_check_frequency(f"frequencies[{i}]", f) for i, f in enumerate(frequencies)]
    order = sorted(range(len(freqs)), key=lambda i: -freqs[i])  # highest frequency first
    levels_f = _beat_tree([freqs[i] for i in order])  # levels_f[L][i]: frequency of node (L, i)
    maps = {
        f"phases[{i}]": _as_phase_map(f"phases[{i}]", p, wrapped=True) for i, p in enumerate(phases)
    }
    mask = _pixel_mask(maps, valid)
    levels_psi = [[_fill(maps[f"phases[{i}]"], mask) for i in order]]  # each (H, W)
    for L in range(1, len(levels_f)):
        f_prev, psi_prev = levels_f[L - 1], levels_psi[L - 1]
        psi_next = []
        for i in range(len(f_prev) - 1):
            sign = 1.0 if f_prev[i] > f_prev[i + 1] else -1.0
            psi_next.append(np.mod(sign * (psi_prev[i] - psi_prev[i + 1]), TWO_PI))  # Eq. (6)
        levels_psi.append(psi_next)
    absolute = levels_psi[-1][0]  # (H, W); absolute because final <= 1
    reliability = np.ones(mask.shape)
    for L in range(len(levels_f) - 2, 0, -1):  # down the upper levels: each refines the absolute phase
        step = _unwrap_on_mask(levels_psi[L][0], absolute, levels_f[L][0], levels_f[L + 1][0], mask)
        reliability = np.minimum(reliability, step.reliability)
        absolute = np.where(mask, step.absolute_phase, 0.0)
    result = _unwrap_on_mask(levels_psi[0][0], absolute, levels_f[0][0], levels_f[1][0], mask)  # level 0: f_1
    reliability = np.minimum(reliability, result.reliability)
    return Unwrapped(
        fringe_order=result.fringe_order,
        absolute_phase=result.absolute_phase,
        valid=result.valid,
        reliability=np.where(mask, reliability, 0.0),
    )


def nt_period_pair(f_h, f_l, extent) -> tuple[int, int]:
    """Coprime integer periods ``(p_h, p_l)`` of a number-theoretic (NT) frequency pair.

    Parameters
    ----------
    f_h, f_l : float
        Frequencies in periods across the projector extent, > 0, distinct, each within a relative
        1e-9 of a fraction with denominator <= 1000 (e.g. 64 and 10.9).
    extent : float
        Projector extent ``W`` along the fringe axis in projector pixels, > 0.

    Returns
    -------
    p_h, p_l : int
        Coprime integers with ``lambda_h : lambda_l = p_h : p_l``, where ``lambda = extent / f`` is
        the period in projector pixels. The common unit is ``u = lambda_h / p_h`` pixels, and the
        extent is ``f_h * p_h`` units. Example: ``(64, 10.9, 912) -> (109, 640)``.

    Raises
    ------
    ValueError
        If a frequency is not > 0 and finite, the frequencies are equal or not close to small
        rationals, or the pair is ambiguous: ``LCM(p_h, p_l) < f_h * p_h`` (the condition after
        Eq. (8) of the paper, ``LCM(lambda_h, lambda_l) >= W``).
    """
    f_h = _check_frequency("f_h", f_h)
    f_l = _check_frequency("f_l", f_l)
    extent = _check_extent(extent)
    if f_h == f_l:
        raise ValueError(f"NT needs two different frequencies; got f_h = f_l = {f_h:g}")
    p_h, p_l, extent_units = _nt_periods(f_h, f_l)
    lcm = math.lcm(p_h, p_l)
    if lcm < extent_units:
        unit_px = extent / f_h / p_h
        raise ValueError(
            f"ambiguous NT pair: f_h = {f_h:g}, f_l = {f_l:g} over extent {extent:g} px give "
            f"lambda_h : lambda_l = {p_h} : {p_l} (unit {unit_px:.6g} px); LCM({p_h}, {p_l}) = "
            f"{lcm} < extent {_fmt_fraction(extent_units)} units, so fringe-order pairs repeat "
            "within the projector (Eq. (8) needs LCM(lambda_h, lambda_l) >= W)"
        )
    return p_h, p_l


def nt_lookup_table(f_h, f_l, extent) -> NTLookupTable:
    """Lookup table of Eq. (9) over the fringe-order pairs that occur across the projector.

    Parameters
    ----------
    f_h, f_l : float
        Frequencies in periods across the projector extent, > 0, distinct (e.g. 64 and 10.9).
    extent : float
        Projector extent ``W`` along the fringe axis in projector pixels, > 0.

    Returns
    -------
    NTLookupTable
        Sorted keys ``lambda_h*k_h - lambda_l*k_l`` (pixels) of every pair ``(k_h, k_l)`` of some
        ``x_p`` in ``[0, W)``, with the pairs and the noise tolerance.

    Raises
    ------
    ValueError
        If a frequency or the extent is not > 0 and finite, the frequencies are equal, or two
        different pairs share a key (the pair is ambiguous: ``LCM(lambda_h, lambda_l) < W``, the
        condition after Eq. (8) of the paper).

    Notes
    -----
    The pair only changes where ``x_p`` crosses a multiple of ``lambda_h`` or ``lambda_l``, so the
    pairs at the midpoints of the segments between those breakpoints are all the pairs (fewer than
    ``ceil(f_h) + ceil(f_l)``). Example 64 / 10.9 over 912 px: 74 pairs, keys in
    ``(-lambda_h, lambda_l) = (-14.25, 83.67)`` px, smallest gap 0.392 px, so ``tolerance_px`` =
    0.196 px and ``tolerance_rad`` = 0.0126 rad; most gaps are 1.44 px or 1.83 px.
    """
    f_h = _check_frequency("f_h", f_h)
    f_l = _check_frequency("f_l", f_l)
    extent = _check_extent(extent)
    if f_h == f_l:
        raise ValueError(f"NT needs two different frequencies; got f_h = f_l = {f_h:g}")
    lambda_h, lambda_l = extent / f_h, extent / f_l
    breaks = np.union1d(lambda_h * np.arange(math.ceil(f_h)), lambda_l * np.arange(math.ceil(f_l)))
    breaks = breaks[breaks < extent]
    edges = np.append(breaks, extent)  # (S + 1,) segment ends, px
    length = np.diff(edges)
    mid = 0.5 * (edges[:-1] + edges[1:])[length > _NT_SEGMENT_EPS * extent]  # drop coincident breakpoints
    k_h = np.floor(mid / lambda_h).astype(np.int64)
    k_l = np.floor(mid / lambda_l).astype(np.int64)
    key = lambda_h * k_h - lambda_l * k_l  # (S,) px
    order = np.argsort(key, kind="stable")
    key, k_h, k_l = key[order], k_h[order], k_l[order]
    gaps = np.diff(key)
    if key.size < 2 or gaps.min() <= _NT_SEGMENT_EPS * extent:
        i = int(np.argmin(gaps)) if key.size >= 2 else 0
        raise ValueError(
            f"ambiguous NT pair: f_h = {f_h:g}, f_l = {f_l:g} over extent {extent:g} px give the same key "
            f"{key[i]:.6g} px to the fringe-order pairs ({k_h[i]}, {k_l[i]}) and ({k_h[min(i + 1, key.size - 1)]}, "
            f"{k_l[min(i + 1, key.size - 1)]}), so they repeat within the projector (Eq. (8) needs "
            "LCM(lambda_h, lambda_l) >= W)"
        )
    below, above = _nearest_outside_keys(float(key[0]), float(key[-1]), lambda_h, lambda_l, math.ceil(f_l),
                                         _NT_SEGMENT_EPS * extent)
    return NTLookupTable(key_px=key, k_h=k_h.astype(np.int32), k_l=k_l.astype(np.int32),
                         lambda_h_px=lambda_h, lambda_l_px=lambda_l, tolerance_px=0.5 * float(gaps.min()),
                         outside_low_px=below, outside_high_px=above)


def _nearest_outside_keys(smallest, largest, lambda_h, lambda_l, n_low, eps) -> tuple[float, float]:
    """The largest key below ``smallest`` and the smallest key above ``largest`` (pixels, farther than ``eps``)
    of ``lambda_h*k_h - lambda_l*k_l`` over ``k_l`` in ``[0, n_low)`` and every integer ``k_h``: the nearest
    pairs beyond the table's keys, none of which occurs on the projector."""
    shift = lambda_l * np.arange(n_low)  # (n_low,) px
    below = lambda_h * (np.ceil((smallest - eps + shift) / lambda_h) - 1.0) - shift
    above = lambda_h * (np.floor((largest + eps + shift) / lambda_h) + 1.0) - shift
    return float(below.max()), float(above.min())


def unwrap_nt(psi_h, psi_l, f_h, f_l, extent, *, valid=None) -> Unwrapped:
    """Number-theoretic (NT) temporal phase unwrapping, Eqs. (8)-(9) of the paper.

    Parameters
    ----------
    psi_h, psi_l : ndarray, shape (H, W)
        Wrapped phases of the two frequencies in radians, ``[0, 2*pi)``; NaN marks an invalid pixel.
    f_h, f_l : float
        Frequencies in periods across the projector extent, > 0, distinct, forming an unambiguous
        pair (e.g. 64 and 10.9; see :func:`nt_lookup_table`).
    extent : float
        Projector extent ``W`` along the fringe axis in projector pixels, > 0.
    valid : ndarray of bool, shape (H, W), optional
        Pixels to unwrap; inputs must be finite where it is True.

    Returns
    -------
    Unwrapped
        Fringe order and absolute phase of ``f_h``. ``reliability`` is the distance of the key to
        its entry's nearest decision boundary over ``tolerance_px``, clipped to ``[0, 1]``. A pixel
        whose key lies outside every entry's decision cell (beyond the smallest or largest key, nearer
        to a pair that cannot occur on the projector) is invalid (not an exception) and counted in
        ``n_rejected``.

    Notes
    -----
    The measured key ``K = (lambda_l*psi_l - lambda_h*psi_h)/(2*pi)`` (pixels; Eq. (8) with
    ``lambda = W/f``) equals ``lambda_h*k_h - lambda_l*k_l`` without noise; the pair is the
    table entry nearest to ``K`` (Eq. (9), ``np.searchsorted`` on the sorted keys). A phase error
    ``d_h``, ``d_l`` moves ``K`` by ``(lambda_l*d_l - lambda_h*d_h)/(2*pi)`` pixels, so every pixel
    is right while that stays below ``tolerance_px`` = half the smallest gap between table keys,
    i.e. for ``|d_h|, |d_l| < tolerance_rad = 2*pi*tolerance_px/(lambda_h + lambda_l)``
    (64 / 10.9 / 912 px: 0.196 px, 0.0126 rad); pixels whose entry has wider gaps tolerate more.
    With Gaussian phase noise of std ``sigma`` the key error has std
    ``sigma*sqrt(lambda_h**2 + lambda_l**2)/(2*pi)`` pixels.

    The same decision as an exhaustive search over the low order (for each ``k_l`` in
    ``[0, ceil(f_l))`` predict the high phase ``(f_h/f_l)*(psi_l + 2*pi*k_l)``, take the nearest ``k_h``
    and keep the candidate of the smallest residual): that residual is the key's distance to
    ``lambda_h*k_h - lambda_l*k_l`` over ``lambda_h``, so wherever the search's best candidate is a pair
    that occurs on the projector, NT returns it; where the search's best is a pair that cannot occur
    (``k_h`` off the projector, e.g. at a mixed pixel), NT returns the nearest pair that can, or rejects
    the key beyond the table's ends (tests/fpp/test_tpu_nt.py checks this on random frequency pairs and
    rendered outside rigs).
    """
    table = nt_lookup_table(f_h, f_l, extent)
    psi_h = _as_phase_map("psi_h", psi_h, wrapped=True)
    psi_l = _as_phase_map("psi_l", psi_l, wrapped=True)
    mask = _pixel_mask({"psi_h": psi_h, "psi_l": psi_l}, valid)
    psi_h = _fill(psi_h, mask)
    key_px = (table.lambda_l_px * _fill(psi_l, mask) - table.lambda_h_px * psi_h) / TWO_PI  # Eq. (8), (H, W)
    index, margin_px = table.match(key_px)  # Eq. (9)
    inside = margin_px >= 0.0
    ok = mask & inside
    k_h = np.where(ok, table.k_h[index], 0).astype(np.int32)
    reliability = np.clip(margin_px / table.tolerance_px, 0.0, 1.0)
    return Unwrapped(
        fringe_order=k_h,
        absolute_phase=np.where(ok, psi_h + TWO_PI * k_h, np.nan),
        valid=ok,
        reliability=np.where(ok, reliability, 0.0),
        n_rejected=int(np.count_nonzero(mask & ~inside)),
    )


def unwrap(method, psi_h, psi_l, f_h, f_l, *, extent=None, valid=None) -> Unwrapped:
    """Two-frequency temporal phase unwrapping by method name.

    Parameters
    ----------
    method : {"mf", "mw", "nt"}
        :func:`unwrap_mf` (Eq. (5)), :func:`unwrap_mw` (Eqs. (6)-(7)) or :func:`unwrap_nt`
        (Eqs. (8)-(9)).
    psi_h, psi_l : ndarray, shape (H, W)
        Wrapped phases in radians, ``[0, 2*pi)``; NaN marks an invalid pixel.
    f_h, f_l : float
        Frequencies in periods across the projector extent, > 0.
    extent : float, optional
        Projector extent in projector pixels; required for ``"nt"``, ignored otherwise.
    valid : ndarray of bool, shape (H, W), optional
        Pixels to unwrap.

    Returns
    -------
    Unwrapped
    """
    if method not in TWO_FREQUENCY_METHODS:
        raise ValueError(f"unknown TPU method {method!r}; expected one of {', '.join(TWO_FREQUENCY_METHODS)}")
    if method == "mf":
        return unwrap_mf(psi_h, psi_l, f_h, f_l, valid=valid)
    if method == "mw":
        return unwrap_mw(psi_h, psi_l, f_h, f_l, valid=valid)
    if extent is None:
        raise ValueError("method 'nt' needs extent (projector pixels along the fringe axis); got None")
    return unwrap_nt(psi_h, psi_l, f_h, f_l, extent, valid=valid)


# --------------------------------------------------------------------------------------------
# Private kernels and checks
# --------------------------------------------------------------------------------------------


def _unwrap_on_mask(psi_h, Psi_l, f_h, f_l, mask) -> Unwrapped:
    """Eq. (5) on finite (H, W) inputs: ``k_h = Round[(f_h*Psi_l - f_l*psi_h)/(2*pi*f_l)]``."""
    q = ((f_h / f_l) * Psi_l - psi_h) / TWO_PI  # (H, W)
    k, reliability = _round_with_reliability(q)
    k = np.where(mask, k, 0).astype(np.int32)
    return Unwrapped(
        fringe_order=k,
        absolute_phase=np.where(mask, psi_h + TWO_PI * k, np.nan),  # Eq. (3)
        valid=mask.copy(),
        reliability=np.where(mask, reliability, 0.0),
    )


def _mod_two_pi(difference):
    """``np.mod(difference, 2*pi)``, in place, for a difference of two wrapped phases (in ``(-4*pi, 4*pi)``):
    the same numbers (numpy's ``fmod`` step, ``x -/+ 2*pi``, is exact there) in masked passes instead of a
    float ``divmod`` (several times slower)."""
    high = difference >= TWO_PI
    np.add(difference, TWO_PI, out=difference, where=difference < 0)
    np.add(difference, TWO_PI, out=difference, where=difference < 0)  # below -2*pi (tolerance of the inputs)
    np.subtract(difference, TWO_PI, out=difference, where=high)
    return difference


def _round_with_reliability(q):
    """Nearest integers of ``q`` (int64) and reliability ``1 - 2*|q - Round(q)|`` in [0, 1]."""
    rounded = np.rint(q)
    reliability = np.clip(1.0 - 2.0 * np.abs(q - rounded), 0.0, 1.0)
    return rounded.astype(np.int64), reliability


def _fill(values, mask):
    """Copy of ``values`` with 0 where ``mask`` is False, so no NaN reaches the integer casts."""
    return np.where(mask, values, 0.0)


def _check_frequency(name, value) -> float:
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number of fringe periods > 0; got {value!r}") from None
    if not math.isfinite(f) or f <= 0.0:
        raise ValueError(
            f"{name} must be a finite frequency > 0 (fringe periods across the projector); got {value!r}"
        )
    return f


def _check_extent(value) -> float:
    try:
        extent = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"extent must be a number of projector pixels > 0; got {value!r}") from None
    if not math.isfinite(extent) or extent <= 0.0:
        raise ValueError(f"extent must be a finite number of projector pixels > 0; got {value!r}")
    return extent


def _check_equivalent_frequency(f_h, f_l) -> float:
    f_eq = f_h - f_l
    if not 0.0 < f_eq <= 1.0:
        raise ValueError(
            "multi-wavelength unwrapping needs an equivalent frequency f_eq = f_h - f_l in (0, 1] so "
            f"the equivalent phase is absolute (Eqs. (6)-(7)); got f_h = {f_h:g}, f_l = {f_l:g}, "
            f"f_eq = {f_eq:g}"
        )
    return f_eq


def _check_mf_frequencies(f_h, f_l) -> tuple[float, float]:
    """``(f_h, f_l)`` as floats for MF (Eq. (5)): both positive and finite, ``f_l <= 1`` (so ``k_l = 0``)."""
    f_h = _check_frequency("f_h", f_h)
    f_l = _check_frequency("f_l", f_l)
    if f_l > 1.0:
        raise ValueError(
            f"unwrap_mf needs f_l <= 1 so the low wrapped phase is already absolute (k_l = 0); got "
            f"f_l = {f_l:g}. Unwrap the low phase first and call unwrap_with_reference, or use "
            "unwrap_heterodyne / unwrap_nt"
        )
    return f_h, f_l


def _as_phase_map(name, values, *, wrapped, dtype=np.float64) -> np.ndarray:
    """``values`` as a float64 (H, W) array (``dtype``; a float32 input is not copied for float32), NaN allowed;
    wrapped phases must lie in [0, 2*pi)."""
    array = np.asarray(values)
    if array.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be a real-valued array of radians; got dtype {array.dtype}")
    array = array.astype(dtype, copy=dtype != np.float64)
    if array.ndim != 2 or array.size == 0:
        raise ValueError(f"{name} must be a non-empty 2-D array (H, W); got shape {array.shape}")
    low, high = float(np.fmin.reduce(array, axis=None)), float(np.fmax.reduce(array, axis=None))  # skip NaN
    if np.isnan(low):
        raise ValueError(f"{name} is all NaN; there is no pixel to unwrap")
    if np.isinf(low) or np.isinf(high):
        raise ValueError(f"{name} must not contain inf; mark invalid pixels with NaN instead")
    if wrapped and (low < -_WRAP_TOLERANCE_RAD or high >= TWO_PI + _WRAP_TOLERANCE_RAD):
        raise ValueError(
            f"{name} must be a wrapped phase in [0, 2*pi); got values in [{low:.6g}, {high:.6g}]"
            " (map a phase in (-pi, pi] with np.mod(psi, 2*pi))"
        )
    return array


def _pixel_mask(maps, valid) -> np.ndarray:
    """(H, W) bool: pixels whose maps are all finite, restricted to the caller's ``valid`` mask."""
    names = list(maps)
    shape = maps[names[0]].shape
    for name in names[1:]:
        if maps[name].shape != shape:
            raise ValueError(
                f"{names[0]} and {name} must have the same shape; got {shape} and {maps[name].shape}"
            )
    finite = np.ones(shape, dtype=bool)
    for array in maps.values():
        finite &= ~np.isnan(array)
    if valid is None:
        return finite
    valid = np.asarray(valid)
    if valid.dtype != bool or valid.shape != shape:
        raise ValueError(
            f"valid must be a bool array of shape {shape} like {names[0]}; got dtype {valid.dtype}, "
            f"shape {valid.shape}"
        )
    n_bad = int(np.count_nonzero(valid & ~finite))
    if n_bad:
        raise ValueError(
            f"{n_bad} pixels are NaN in {', '.join(names)} where valid is True; mark them False "
            "in valid or pass finite phases there"
        )
    return valid.copy()


def _as_small_fraction(name, f) -> Fraction:
    fraction = Fraction(str(f)).limit_denominator(_MAX_DENOMINATOR)
    if abs(float(fraction) - f) > _RATIONAL_RELATIVE_TOLERANCE * f:
        raise ValueError(
            f"{name} = {f!r} is not close to a rational number with denominator <= "
            f"{_MAX_DENOMINATOR} (nearest {fraction}); NT needs rational frequencies such as 10.9"
        )
    return fraction


def _nt_periods(f_h, f_l):
    """Coprime ``(p_h, p_l)`` with ``p_h/p_l = f_l/f_h`` and the extent ``f_h*p_h`` in those units."""
    frac_h = _as_small_fraction("f_h", f_h)
    frac_l = _as_small_fraction("f_l", f_l)
    ratio = frac_l / frac_h  # lambda_h / lambda_l, exact and in lowest terms
    return ratio.numerator, ratio.denominator, frac_h * ratio.numerator


def _beat_tree(freqs):
    """Frequencies of the heterodyne beat tree, level 0 = ``freqs`` (sorted highest first).

    Level ``L`` holds ``|f_i - f_(i+1)|`` of neighbours of level ``L - 1``; the single node of the
    last level must lie in (0, 1].
    """
    for a, b in pairwise(freqs):
        if a == b:
            raise ValueError(f"unwrap_heterodyne needs distinct frequencies; got {a:g} twice")
    levels = [list(freqs)]
    while len(levels[-1]) > 1:
        prev = levels[-1]
        beats = [abs(a - b) for a, b in pairwise(prev)]
        if 0.0 in beats:
            raise ValueError(
                f"heterodyne beat tree level {len(levels)}: values {_fmt(prev)} contain two equal "
                f"neighbours; their beat is 0, so the tree cannot reach a beat in (0, 1] from "
                f"frequencies {_fmt(freqs)}"
            )
        levels.append(beats)
    final = levels[-1][0]
    if final > 1.0:
        raise ValueError(
            f"heterodyne final beat must be in (0, 1] so its phase needs no unwrapping; got "
            f"{final:.6g} > 1, the beat of level-{len(levels) - 2} values {_fmt(levels[-2])} "
            "(beat tree: "
            + "; ".join(f"level {L}: {_fmt(fs)}" for L, fs in enumerate(levels))
            + "). Choose frequencies whose final beat is <= 1"
        )
    return levels


def _fmt(values) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]"


def _fmt_fraction(value: Fraction) -> str:
    return str(value.numerator) if value.denominator == 1 else f"{float(value):.6g}"
