"""Neighbour support of a fringe order: how much of a pixel's surroundings, weighted by their own confidence, puts
its absolute phase where its order does.

A smooth surface's absolute phase ``U = k + psi / 2 pi`` (Eq. (3), in periods) changes between neighbouring pixels
by its local gradient ``G`` (periods per pixel) and nothing more, so each neighbour ``q`` of ``p`` predicts
``U_p = U_q - G_p . (q - p)``; a prediction within ``tolerance`` periods of ``U_p`` *agrees* with ``p``'s order.
:func:`neighbour_support` is the share of ``p``'s valid neighbours (window of ``2 radius + 1`` pixels) that agree,
each counted with its own confidence: 1 where every neighbour agrees and is sure of its own order, about 1/2 for a
pixel at a depth edge (half of its window on the other surface) or in a patch made up by a vote, 0 where nothing
around it confirms it.

It is the spatial half of a confidence whose temporal half (the rounding margin of a method, the network's distance
to an integer order, its agreement with its prior: :mod:`dptpu.fpp.confidence`) fails where the temporal prior is
too noisy to say anything: MW at 3 steps and 2 sigma amplifies the phase noise ``f_h / (f_h - f_l)`` = 64 times, so
the coarse order is often 2 or more orders off while the order the network and its neighbour consensus publish is
right, and smoothly joined to confident neighbours. Wrong orders the consensus made up sit at edges or in patches
whose neighbours are either on another surface or unconfident themselves: their support stays near or below 1/2.

The gradient comes from the wrapped phase alone (:func:`phase_gradient`: wrapped neighbour differences averaged over
a small window), never from the orders being judged.
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = ["DEFAULT_SUPPORT_RADIUS", "DEFAULT_SUPPORT_TOLERANCE", "neighbour_support", "phase_gradient"]

#: Half-width of the support window, pixels (7 x 7: 48 neighbours, about one fringe period at the project's
#: densest fringes of 4-7 pixels; a wrong patch smaller than half the window cannot support itself).
DEFAULT_SUPPORT_RADIUS = 3
#: Largest disagreement, in periods, between a neighbour's prediction of a pixel's absolute phase and the pixel's:
#: a wrong order is a whole period off, the noise of a 3-step phase at the paper's 2 sigma ~0.01 period.
DEFAULT_SUPPORT_TOLERANCE = 0.25
#: Half-width of the window averaging the wrapped differences of :func:`phase_gradient`.
GRADIENT_RADIUS = 2
#: Pixels whose windows :func:`neighbour_support` compares at once (80 neighbours each: 2.6 MB a float32 array).
_SUPPORT_CHUNK = 8192


def _box_sum(values: np.ndarray, radius: int) -> np.ndarray:
    size = (2 * radius + 1, 2 * radius + 1)
    return cv2.boxFilter(values, -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)


def phase_gradient(wrapped: np.ndarray, valid: np.ndarray,
                   radius: int = GRADIENT_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """Local gradient of the absolute phase along image rows (y) and columns (x), periods per pixel, float32.

    The mean over a ``(2 radius + 1)^2`` window of the wrapped differences ``wrap(psi(p + e) - psi(p)) / 2 pi``
    between valid neighbours (right while fringes are wider than 2 pixels); 0 where the window has no valid pair.
    """
    frac = (np.asarray(wrapped, dtype=np.float64) / (2.0 * np.pi)).astype(np.float32)
    valid = np.asarray(valid, dtype=bool)
    size = (2 * radius + 1, 2 * radius + 1)
    gradients = []
    for axis in (0, 1):
        step = np.diff(frac, axis=axis)
        step -= np.rint(step)
        inner = (slice(0, -1), slice(None)) if axis == 0 else (slice(None), slice(0, -1))  # the last row/column: 0
        pair = np.zeros(frac.shape, bool)
        np.logical_and(valid[1:] if axis == 0 else valid[:, 1:], valid[inner], out=pair[inner])
        steps = np.zeros(frac.shape, np.float32)
        np.copyto(steps[inner], step, where=pair[inner])
        # the count of pairs summed from uint8: whole numbers, the same float32 as a float32 map's sums
        count = cv2.boxFilter(pair.view(np.uint8), cv2.CV_32F, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
        gradients.append(_box_sum(steps, radius) / np.maximum(count, np.float32(1.0)))
    return gradients[0], gradients[1]


def neighbour_support(order: np.ndarray, wrapped: np.ndarray, valid: np.ndarray, confidence: np.ndarray, *,
                      radius: int = DEFAULT_SUPPORT_RADIUS, tolerance: float = DEFAULT_SUPPORT_TOLERANCE,
                      where: np.ndarray | None = None) -> np.ndarray:
    """Support ``(H, W)`` float32 in ``[0, 1]`` of each valid pixel's ``order`` by its neighbours (module docstring).

    ``sum_q agree(q, p) c_q / n_p`` over the valid neighbours ``q`` of the ``(2 radius + 1)^2`` window (``n_p`` of
    them; ``p`` itself excluded), ``agree``: ``|U_q - G_p . (q - p) - U_p| < tolerance`` periods, ``c_q`` the
    neighbour's own confidence clipped to ``[0, 1]``. 0 where ``p`` is not valid or has no valid neighbour.

    Parameters
    ----------
    order : ndarray (H, W) int
        Fringe order of the high frequency.
    wrapped : ndarray (H, W)
        Its wrapped phase, radians (NaN allowed where not ``valid``).
    valid : ndarray (H, W) bool
    confidence : ndarray (H, W)
        Each pixel's own confidence (without neighbour support).
    where : ndarray (H, W) bool, optional
        Pixels to compute (0 elsewhere); default every valid one. The pixels are gathered by flat index, so the cost
        is that of ``where``'s pixels (a caller that needs the support only below some confidence passes those).
    """
    if radius < 1 or not 0.0 < tolerance <= 0.5:
        raise ValueError(f"neighbour_support needs radius >= 1 and tolerance in (0, 0.5]; got {radius}, {tolerance}")
    valid = np.asarray(valid, dtype=bool) & np.isfinite(wrapped)
    psi = np.where(valid, wrapped, 0.0)
    support = np.zeros(psi.shape, np.float32)
    todo = valid if where is None else valid & np.asarray(where, dtype=bool)
    pixels = np.flatnonzero(todo)
    if pixels.size == 0:
        return support
    gy, gx = phase_gradient(psi, valid)
    grad_y, grad_x = gy.ravel()[pixels], gx.ravel()[pixels]
    size = (2 * radius + 1, 2 * radius + 1)
    # valid ones, p excluded (p is valid); summed from uint8: whole numbers, the float32 map's sums
    neighbours = cv2.boxFilter(valid.view(np.uint8), cv2.CV_32F, size, normalize=False,
                               borderType=cv2.BORDER_CONSTANT).ravel()[pixels] - np.float32(1.0)
    # U (periods; float64, then float32) and the weight (the confidence clipped to [0, 1], NaN as 0) in maps padded
    # by radius: NaN and 0 beyond the image and where not valid
    height, width = psi.shape
    padded = np.full((height + 2 * radius, width + 2 * radius), np.nan, np.float32)
    inner = (slice(radius, radius + height), slice(radius, radius + width))
    np.copyto(padded[inner], np.asarray(order, dtype=np.float64) + psi / (2.0 * np.pi), where=valid)
    padded_weight = np.zeros(padded.shape, np.float32)
    weight = padded_weight[inner]
    np.copyto(weight, confidence, where=valid)  # rounded to float32 before the clip: the same as after it
    np.maximum(weight, np.float32(0.0), out=weight)
    np.minimum(weight, np.float32(1.0), out=weight)
    np.copyto(weight, np.float32(0.0), where=np.isnan(weight))
    padded, padded_weight = padded.ravel(), padded_weight.ravel()
    padded_width = width + 2 * radius
    rows, cols = np.divmod(pixels, width)
    centre = (rows + radius) * padded_width + cols + radius  # flat indices into the padded maps
    own = padded[centre]
    span = np.arange(-radius, radius + 1)
    dy, dx = (a.ravel() for a in np.meshgrid(span, span, indexing="ij"))
    others = (dy != 0) | (dx != 0)  # the window but p, row by row
    dy, dx = dy[others], dx[others]
    shifts = dy * padded_width + dx
    dy, dx = dy.astype(np.float32), dx.astype(np.float32)  # whole numbers: float32 products as with Python ints
    agreeing = np.empty(pixels.size, np.float32)
    with np.errstate(invalid="ignore"):
        for chunk in range(0, pixels.size, _SUPPORT_CHUNK):
            part = slice(chunk, chunk + _SUPPORT_CHUNK)
            shift = centre[part, None] + shifts[None, :]  # (n, window - 1)
            # U_q - G_p . (q - p) - U_p, periods (NaN for an invalid q: never agrees)
            difference = padded[shift] - own[part, None]
            difference -= grad_y[part, None] * dy + grad_x[part, None] * dx
            agree = np.where(np.abs(difference) < tolerance, padded_weight[shift], np.float32(0.0))
            # summed in the window's order, one neighbour after the other (float32, as a running sum from 0)
            agreeing[part] = np.cumsum(agree, axis=1)[:, -1] + np.float32(0.0)
    support.ravel()[pixels] = agreeing / np.maximum(neighbours, 1.0)
    return support
