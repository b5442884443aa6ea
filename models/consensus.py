"""Pixel-level post-processing of a fringe order: neighbour consensus on the absolute phase (no torch).

The network's order (:mod:`dptpu.models.inference`, ``rint`` of its continuous output) is decided at
stride 4: its blend towards a smooth patch reference ``r`` breaks pixels within 1-2 px of depth edges
and mask borders, where ``r`` mixes two surfaces (docs/model-eval.md, "Error analysis": 70 % of its
errors on the unseen rig, MF at 1 sigma). This step decides each pixel again at full resolution, with
nothing but the measured wrapped phase ``psi_h`` and the orders themselves (no ground truth):

1. **Consistent classical pixels** (:func:`prefer_consistent_classical`): where the network changed the
   classical order but the classical absolute phase ``k_c + psi_h / 2pi`` (Eq. (3), in periods) agrees
   within half a period with that of most of the pixel's valid 8-neighbours, the classical order is
   kept. A wrong classical order is an isolated jump of one or more periods, which its neighbours do not
   share; a right one at a depth edge is shared by its same-surface neighbours.
2. **Neighbour vote** (:func:`vote_orders`): every valid pixel ``q`` of the ``(2R+1)^2`` window around
   ``p`` predicts ``p``'s absolute phase as ``U_q - G_p . (q - p)`` (``G_p``: the local phase gradient in
   periods per pixel, from wrapped differences of ``psi_h``, :func:`phase_gradient`), and so votes for
   the order ``rint(U_q - G_p . (q - p) - psi_h(p) / 2pi)``. Both the current orders and the classical
   ones vote (a wrong strip of the network along an edge is outvoted where the classical orders of the
   strip are mostly right). The order with most votes wins (the pixel's own order on ties; it counts
   once itself). All neighbours on another surface, a step of ``D`` periods away, vote for ``k + rint(D)``,
   so the surface with most pixels in the window decides: right along smooth edges, but the vote erodes
   sharp convex corners of a region by a pixel or two (measured on analytic step scenes, below). The
   passes use windows of radius 1, 3, 3, 3, 3 (:data:`DEFAULT_RADII`), or 1, 3, 5, 6, 6, 6 (:data:`WIDE_RADII`)
   where the classical order is noisy (it breaks at least half of its neighbour pairs, :func:`break_share`:
   MW at 2 sigma and high f_h), each on the previous pass's orders,
   so a strip is eaten from its same-surface side; a pass re-decides only the pixels within its radius of
   two 4-neighbours whose phases disagree (elsewhere the votes confirm the order), and a pass of the same
   radius as the last one only those near the last one's changes, which keeps it cheap on clean maps.

Measured on the unseen-rig test set and the nominal held-out set: docs/model-eval.md. On the analytic step
scenes of :mod:`dptpu.models.toy_dataset` (axis-aligned blocks) it helps on 120x160 scenes (MF, 1 sigma, 4
scenes x 4 frequencies: classical 94.19 %, shipped model rounded 93.31 %, with the consensus 99.31 %) but
breaks block corners where the classical order was nearly perfect (64x64, f_h = 32: classical 99.90 %, the
vote on the classical order 96.44 %).
"""
from __future__ import annotations

import cv2
import numpy as np

from dptpu.fpp.order_support import phase_gradient as support_phase_gradient

__all__ = ["CLASSICAL_SHARE", "DEFAULT_RADII", "WIDE_RADII", "WIDE_SHARE", "break_share", "consensus_order",
           "phase_gradient", "prefer_consistent_classical", "vote_orders"]

#: Window half-width of each pass of the vote, pixels (3x3, then four passes of 7x7). Measured on the
#: unseen-rig set (MF, 2 sigma, mean over f_h): passes 1,3,3 97.48 %, 1,3,3,3,3 97.85 % (docs/model-eval.md).
DEFAULT_RADII = (1, 3, 3, 3, 3)
#: Window half-widths for a noisy classical order (:func:`break_share` >= :data:`WIDE_SHARE`): more neighbours
#: outvote more noise, but erode more of a region's corners. Measured on the unseen-rig set (320x240, MW, 2 sigma,
#: f_h >= 60, network + consensus): radii 1,3,3,3,3 mean 97.19 % (lowest 95.44 %), 1,3,5,6,6,6 98.56 (97.92).
WIDE_RADII = (1, 3, 5, 6, 6, 6)
#: Share of broken neighbour pairs of the classical order (:func:`break_share`) from which the vote takes
#: :data:`WIDE_RADII`. On the unseen-rig set: 1-30 % for MF at 1 sigma up to f_h = 56, 50-84 % for MW at
#: 2 sigma from f_h = 56 on; 0-2 % for NT's MF-representation order (:mod:`dptpu.models.nt_prior`).
WIDE_SHARE = 0.5
#: Share of the valid 8-neighbours (at least 3) whose classical absolute phase must agree with a pixel's
#: for its classical order to be kept where the network changed it.
CLASSICAL_SHARE = 0.6
#: Half-width of the window that averages the wrapped phase differences of :func:`phase_gradient`.
GRADIENT_RADIUS = 2


def _check(name: str, array, shape=None) -> np.ndarray:
    array = np.asarray(array)
    if array.ndim != 2 or (shape is not None and array.shape != shape):
        expected = "(H, W)" if shape is None else f"{shape} like wrapped_high"
        raise ValueError(f"{name} must be a {expected} array; got shape {array.shape}")
    return array


def phase_gradient(wrapped_high, valid, radius: int = GRADIENT_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """Local gradient of the absolute phase, periods per pixel, along rows (y) and columns (x).

    The mean over the ``(2 radius + 1)^2`` window of the wrapped differences ``wrap(psi(p + e) - psi(p)) /
    2pi`` between valid neighbours (right while the phase changes by less than half a period per pixel,
    i.e. fringes of more than 2 px; ``dptpu unwrap`` refines periods of 4 px or more).

    Parameters
    ----------
    wrapped_high : ndarray (H, W)
        Wrapped phase, radians.
    valid : ndarray (H, W) bool

    Returns
    -------
    gy, gx : ndarray (H, W) float32
        0 where the window has no valid pair.
    """
    return support_phase_gradient(wrapped_high, valid, radius)  # one definition, fpp.order_support's


def prefer_consistent_classical(model_order, classical_order, wrapped_high, valid,
                                share: float = CLASSICAL_SHARE) -> np.ndarray:
    """The network's order, but the classical one where that is consistent with its 8-neighbourhood.

    Parameters
    ----------
    model_order, classical_order : ndarray (H, W) int
    wrapped_high : ndarray (H, W)
        Radians.
    valid : ndarray (H, W) bool
    share : float
        A classical order is consistent when at least ``max(3, ceil(share * n))`` of the ``n`` valid
        8-neighbours have a classical absolute phase within half a period of the pixel's.

    Returns
    -------
    ndarray (H, W) int32
    """
    valid = np.asarray(valid, dtype=bool)
    model_order = np.asarray(model_order)
    classical_order = np.asarray(classical_order)
    absolute = np.where(valid, classical_order + np.asarray(wrapped_high, dtype=np.float64) / (2.0 * np.pi),
                        np.nan).astype(np.float32)  # periods, Eq. (3)
    height, width = absolute.shape
    padded = np.pad(absolute, 1, constant_values=np.nan)
    agree = np.zeros((height, width), np.int16)
    neighbours = np.zeros((height, width), np.int16)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == 0 and dx == 0:
                continue
            other = padded[1 + dy:1 + dy + height, 1 + dx:1 + dx + width]
            neighbours += np.isfinite(other)
            with np.errstate(invalid="ignore"):
                agree += np.abs(other - absolute) < 0.5
    needed = np.maximum(3, np.ceil(share * neighbours))
    keep = valid & (model_order != classical_order) & (agree >= needed)
    return np.where(keep, classical_order, model_order).astype(np.int32)


def vote_orders(order, wrapped_high, valid, *, radii=DEFAULT_RADII, gradient=None, also=None,
                sparse: bool = False) -> np.ndarray:
    """Neighbour vote on the absolute phase (module docstring, step 2), ``(H, W)`` int32.

    Parameters
    ----------
    order : ndarray (H, W) int
        Fringe order to clean; invalid pixels are returned unchanged and do not vote.
    wrapped_high : ndarray (H, W)
        Radians.
    valid : ndarray (H, W) bool
    radii : sequence of int
        Window half-width of each pass, pixels (each >= 1); each pass works on the previous one's orders.
    gradient : (gy, gx), optional
        From :func:`phase_gradient` (computed when not given).
    also : ndarray (H, W) int, optional
        A second order map (the classical one) whose pixels vote too, unchanged between passes.
    sparse : bool
        Only every second offset of each window votes (a checkerboard; half the work).
    """
    radii = [int(r) for r in radii]
    if not radii or min(radii) < 1:
        raise ValueError(f"vote_orders needs radii >= 1 (window half-widths in pixels); got {radii}")
    valid = np.asarray(valid, dtype=bool)
    frac = (np.asarray(wrapped_high, dtype=np.float64) / (2.0 * np.pi)).astype(np.float32)
    gy, gx = phase_gradient(wrapped_high, valid) if gradient is None else gradient
    current = np.asarray(order).astype(np.int32)
    classical = None if also is None else np.where(valid, np.asarray(also) + frac, np.nan).astype(np.float32)
    changed, previous = None, None
    for index, radius in enumerate(radii):
        absolute = np.where(valid, current + frac, np.nan).astype(np.float32)  # U, periods
        todo = _unsettled(absolute, gy, gx, radius)
        if changed is not None and radius == previous:
            # a pixel whose window kept its orders gets the votes of the previous pass again
            todo &= cv2.dilate(changed.astype(np.uint8), np.ones((2 * radius + 1,) * 2, np.uint8)).astype(bool)
        fields = [absolute] if classical is None else [absolute, classical]
        step = _vote_steps(fields, absolute, gy, gx, todo, radius, sparse=sparse)
        changed, previous = step != 0, radius
        if not changed.any() and all(r == radius for r in radii[index + 1:]):
            break  # the remaining passes would cast the same votes
        current = current + step
    return current


def _vote_steps(fields, absolute, gy, gx, todo, radius: int, sparse: bool) -> np.ndarray:
    """The order change the window's votes ask for, per pixel (0 outside ``todo``), ``(H, W)`` int32.

    Only the ``todo`` pixels are counted (gathered by flat index: on the test sets this was faster than
    whole-row operations even when most pixels were to do); ``sparse`` uses every second offset of the
    window (a checkerboard).
    """
    step = np.zeros(absolute.shape, np.int32)
    pixels = np.flatnonzero(todo)
    if pixels.size:
        step.ravel()[pixels] = _gathered_steps(fields, absolute, gy, gx, pixels, radius, sparse)
    return step


def _gathered_steps(fields, absolute, gy, gx, pixels, radius: int, sparse: bool) -> np.ndarray:
    """:func:`_vote_steps` for the flat indices ``pixels`` alone, ``(n,)`` int32.

    Votes for ``k - 1``, ``k`` and ``k + 1`` are counted for every pixel; the pixels whose votes for
    other orders outnumber each of those three counts are voted again with every order counted
    (:func:`_plurality`), so an order off by several periods is corrected too.
    """
    width = absolute.shape[1]
    padded_width = width + 2 * radius
    rows, cols = np.divmod(pixels, width)
    centre = (rows + radius) * padded_width + cols + radius  # flat indices into the padded maps
    padded = [np.pad(field, radius, constant_values=np.nan).ravel() for field in fields]
    own, grad_y, grad_x = absolute.ravel()[pixels], gy.ravel()[pixels], gx.ravel()[pixels]
    offsets = [(dy, dx) for dy in range(-radius, radius + 1) for dx in range(-radius, radius + 1)
               if not ((dy == 0 and dx == 0) or (sparse and (dy + dx) % 2))]
    down = np.zeros(pixels.size, np.int16)
    same = np.ones(pixels.size, np.int16)  # the pixel's own vote
    up = np.zeros(pixels.size, np.int16)
    votes = np.zeros(pixels.size, np.int16)  # all valid votes
    jump = np.empty(pixels.size, np.float32)
    hit = np.empty(pixels.size, bool)
    with np.errstate(invalid="ignore"):
        for dy, dx in offsets:
            expected = own + (grad_y * dy + grad_x * dx)  # p's phase moved to q: U_p + G_p . (q - p)
            shift = centre + (dy * padded_width + dx)
            for field in padded:
                # periods by which q's prediction of p exceeds p's phase: U_q - G_p . (q - p) - U_p
                np.subtract(field[shift], expected, out=jump)
                np.rint(jump, out=jump)
                np.equal(jump, -1.0, out=hit)
                down += hit
                np.equal(jump, 0.0, out=hit)
                same += hit
                np.equal(jump, 1.0, out=hit)
                up += hit
                np.isfinite(jump, out=hit)
                votes += hit
    step = np.where((up > same) & (up > down), 1, np.where((down > same) & (down >= up), -1, 0)).astype(np.int32)
    other = votes + 1 - down - same - up  # votes for orders off by 2 or more
    far = np.flatnonzero((other > same) & (other > up) & (other > down))
    if far.size:
        best, count = _plurality(padded, centre[far], own[far], grad_y[far], grad_x[far], offsets, padded_width)
        wins = count > np.maximum(np.maximum(same[far], up[far]), down[far])
        step[far] = np.where(wins, best, step[far])
    return step


def _plurality(padded, centre, own, grad_y, grad_x, offsets, padded_width) -> tuple[np.ndarray, np.ndarray]:
    """The most voted order change of each pixel and its vote count, ``(n,)`` int32 each.

    The same votes as :func:`_gathered_steps`, sorted per pixel; the longest run of equal values wins
    (the smallest change on ties). Invalid neighbours do not vote.
    """
    none = np.iinfo(np.int16).max  # stands for an invalid neighbour (sorted last)
    steps = np.array(offsets, np.int64)  # (V, 2)
    shift = steps[:, 0] * padded_width + steps[:, 1]
    expected = (own[:, None] + grad_y[:, None] * steps[:, 0].astype(np.float32)
                + grad_x[:, None] * steps[:, 1].astype(np.float32))  # (n, V)
    with np.errstate(invalid="ignore"):
        jumps = np.concatenate([np.rint(field[centre[:, None] + shift] - expected) for field in padded], axis=1)
    table = np.where(np.isfinite(jumps), np.clip(jumps, -30000, 30000), none).astype(np.int16)  # (n, votes)
    table.sort(axis=1, kind="stable")  # radix sort of 16-bit integers
    index = np.arange(table.shape[1])[None, :]
    starts = np.zeros(table.shape, np.int32)
    starts[:, 1:] = np.where(table[:, 1:] != table[:, :-1], index[:, 1:], 0)
    run = index - np.maximum.accumulate(starts, axis=1) + 1  # length of the run ending at each vote
    run[table == none] = 0
    end = np.argmax(run, axis=1)
    rows = np.arange(centre.size)
    return table[rows, end].astype(np.int32), run[rows, end].astype(np.int32)


def _unsettled(absolute: np.ndarray, gy: np.ndarray, gx: np.ndarray, radius: int) -> np.ndarray:
    """Mask ``(H, W)`` of the valid pixels within ``radius`` of a 4-neighbour pair whose phases disagree.

    A pair disagrees when ``rint(U_q - U_p - G . (q - p)) != 0``. Elsewhere the window's current orders
    form one consistent surface with the pixel, so the vote skips it.
    """
    finite = np.isfinite(absolute)
    broken = np.zeros(absolute.shape, np.uint8)
    with np.errstate(invalid="ignore"):
        step_y = np.rint(absolute[1:] - absolute[:-1] - gy[:-1]) != 0
        step_x = np.rint(absolute[:, 1:] - absolute[:, :-1] - gx[:, :-1]) != 0
    step_y &= finite[1:] & finite[:-1]
    step_x &= finite[:, 1:] & finite[:, :-1]
    broken[1:] |= step_y
    broken[:-1] |= step_y
    broken[:, 1:] |= step_x
    broken[:, :-1] |= step_x
    near = cv2.dilate(broken, np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)).astype(bool)
    return near & finite


def break_share(order, wrapped_high, valid, gradient=None) -> float:
    """Share of the valid 4-neighbour pairs whose absolute phases disagree, ``rint(U_q - U_p - G . (q - p)) != 0``.

    Parameters
    ----------
    order : ndarray (H, W) int
    wrapped_high : ndarray (H, W)
        Radians, finite where ``valid``.
    valid : ndarray (H, W) bool
    gradient : (gy, gx), optional
        From :func:`phase_gradient`.

    Returns
    -------
    float
        In ``[0, 1]``; 0.0 without valid pairs. A right order breaks only at depth edges; every wrong pixel of
        a noisy order breaks its pairs.
    """
    valid = np.asarray(valid, dtype=bool)
    gy, gx = phase_gradient(wrapped_high, valid) if gradient is None else gradient
    absolute = np.where(valid, np.asarray(order) + np.asarray(wrapped_high, dtype=np.float64) / (2.0 * np.pi),
                        np.nan)  # periods, Eq. (3)
    pairs_y, pairs_x = valid[1:] & valid[:-1], valid[:, 1:] & valid[:, :-1]
    with np.errstate(invalid="ignore"):
        broken_y = (np.rint(absolute[1:] - absolute[:-1] - gy[:-1]) != 0) & pairs_y
        broken_x = (np.rint(absolute[:, 1:] - absolute[:, :-1] - gx[:, :-1]) != 0) & pairs_x
    pairs = int(np.count_nonzero(pairs_y) + np.count_nonzero(pairs_x))
    return (int(np.count_nonzero(broken_y)) + int(np.count_nonzero(broken_x))) / pairs if pairs else 0.0


def consensus_order(model_order, classical_order, wrapped_high, valid, *, radii=None,
                    sparse: bool = False) -> np.ndarray:
    """Both steps of the module docstring: the post-processed fringe order, ``(H, W)`` int32.

    Parameters
    ----------
    model_order : ndarray (H, W) int
        The network's rounded order.
    classical_order : ndarray (H, W) int
        The classical method's order (Eq. (5), (7) or (9)).
    wrapped_high : ndarray (H, W)
        Wrapped phase of the high frequency, radians (finite where ``valid``).
    valid : ndarray (H, W) bool
        Pixels to decide; the others keep ``model_order``.
    radii : sequence of int, optional
        Of :func:`vote_orders`. Default: :data:`WIDE_RADII` when the classical order breaks at least
        :data:`WIDE_SHARE` of its neighbour pairs (:func:`break_share`), else :data:`DEFAULT_RADII`.
    sparse : bool
        Of :func:`vote_orders`.

    Returns
    -------
    ndarray (H, W) int32
    """
    psi = _check("wrapped_high", wrapped_high)
    shape = psi.shape
    model_order = _check("model_order", model_order, shape)
    classical_order = _check("classical_order", classical_order, shape)
    valid = _check("valid", valid, shape).astype(bool) & np.isfinite(psi)
    psi = np.where(valid, psi, 0.0)
    gradient = phase_gradient(psi, valid)
    if radii is None:
        noisy = break_share(classical_order, psi, valid, gradient) >= WIDE_SHARE
        radii = WIDE_RADII if noisy else DEFAULT_RADII
    start = prefer_consistent_classical(model_order, classical_order, psi, valid)
    return vote_orders(start, psi, valid, radii=radii, gradient=gradient, also=classical_order, sparse=sparse)
