"""Patches whose fringe order the low frequency rejects: the two-frequency agreement judged over a region, not a pixel.

A wrong order of the high frequency moves the low frequency's predicted phase (:mod:`dptpu.fpp.frequency_consistency`):
with ``eps = wrap((f_l / f_h) Phi_h - psi_l)`` (Eq. (3) for each frequency), an order ``e`` too high adds
``2 pi e f_l / f_h``, which modulo ``2 pi`` is ``2 pi e delta`` with ``delta = f_l / f_h - Round(f_l / f_h)``. So

    r = eps / (2 pi delta)

(:func:`order_error_estimate`) is a per-pixel, continuous estimate of the published order's error ``e`` in orders,
unambiguous while ``|e| < 1 / (2 |delta|)`` (MF and MW at ``f_h = 64``: 32 orders; NT at 64 / 10.9: 2.9 orders), and
its noise is the phase noise of the two frequencies times ``1 / (2 pi |delta|)``: 64 / 2pi for MF and MW at
``f_h = 64``, so on a noisy capture a single pixel cannot tell an order one off from the right one (the twin's
12-step captures at the paper's 2 sigma: a robust standard deviation of 0.5 order, 1.2 on dim surfaces). Over a patch
of ``n`` pixels one order off, the median of ``r`` is about ``+-1`` and its standard error ``sqrt(pi / 2) sigma /
sqrt(n)``: the 17 pixels of a 35-pixel patch's testing half (below) put it 6 standard errors from the right order.
Such patches exist: the network and its neighbour consensus make the absolute phase continuous across a real depth
step about one fringe period deep, so a strip beyond the step is one order off while its phase joins the surface
before it without a step (no island border, no flying point; ``docs/nodes.md``, "Confidence").

:func:`rejected_regions` finds them without letting the pixels that propose a patch also judge it (a patch chosen
because its ``r`` is large would otherwise pass any test on the same ``r``): camera noise is independent from pixel
to pixel, so the image is split as a checkerboard into two halves.

1. **Proposal**, on one half: the mean of ``r`` (each pixel's vote clipped to :data:`VOTE_CLIP_ORDERS`, so one wild
   pixel or a patch several orders off does not spread over the window) over the ``(2 radius + 1)^2`` window; the
   candidate patches are the connected components (8-connected, all pixels) where the mean lies nearer to ``s = +1``
   or ``s = -1`` order than to 0 (``s m > 1/2``).
2. **Test**, on the other half's pixels of each candidate (at least :data:`MIN_TEST_PIXELS`): the median ``mu`` of
   ``r``, ``sigma`` the larger of the candidate's robust standard deviation (1.4826 MAD) and the scan's (1.4826
   median ``|r|``), and the published order is rejected where ``s mu > Z sqrt(pi / 2) sigma / sqrt(n)``, ``Z`` =
   ``significance`` (default :data:`DEFAULT_SIGNIFICANCE` = 4 standard errors).
3. Both halves propose in turn; the rejected patches (all their valid pixels) are the union.

The test rejects the published order (its expected ``r`` is 0); it does not claim the prior's order is right, and the
caller drops the patch (confidence 0), it shifts nothing. Where the network is right against a wrong classical
order, ``r`` is centred on 0 whatever the classical order did, and the test keeps the patch. It uses no length,
focal length or noise level: the frequencies, the scan's own residuals and a significance.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from .bracketed_median import bracketed_median
from .frequency_consistency import MAD_TO_SIGMA, consistency_residual

__all__ = ["DEFAULT_RADIUS", "DEFAULT_SIGNIFICANCE", "MIN_TEST_PIXELS", "VOTE_CLIP_ORDERS", "median_and_mad",
           "order_error_estimate", "rejected_regions"]

#: Half-width of the proposal window, pixels (7 x 7: 24-25 proposing pixels, a mean of standard error 0.2 order at
#: the twin's 2 sigma noise).
DEFAULT_RADIUS = 3
#: ``Z``: standard errors of the test half's median by which a patch's ``r`` must lie beyond 0 to reject its order.
DEFAULT_SIGNIFICANCE = 4.0
#: Fewest test pixels of a candidate patch: fewer do not measure its own spread (smaller patches are the per-pixel
#: agreement's, :func:`dptpu.fpp.frequency_consistency.frequency_consistency`).
MIN_TEST_PIXELS = 10
#: Largest vote of one pixel in the proposal mean, orders.
VOTE_CLIP_ORDERS = 2.0
#: sqrt(pi / 2): the standard error of the median of n normal samples is this times sigma / sqrt(n).
_MEDIAN_SE = math.sqrt(math.pi / 2.0)


def order_error_estimate(absolute_high: np.ndarray, wrapped_low: np.ndarray, f_h: float, f_l: float,
                         valid: np.ndarray) -> np.ndarray:
    """``r = eps / (2 pi delta)`` (module docstring) ``(H, W)`` float32, orders; NaN where not ``valid`` or an input is.

    Parameters
    ----------
    absolute_high : ndarray (H, W)
        The published absolute phase of ``f_h``, radians.
    wrapped_low : ndarray (H, W)
        The wrapped phase of ``f_l``, radians.
    f_h, f_l : float
        Periods across the projector (> 0); ``f_l / f_h`` must not be a whole number (no ``delta``).
    valid : ndarray (H, W) bool
    """
    ratio = f_l / f_h if f_h > 0 else math.nan
    delta = ratio - round(ratio) if math.isfinite(ratio) else 0.0
    if not abs(delta) > 1e-9:
        raise ValueError(f"f_l / f_h must be positive and not a whole number; got f_h={f_h}, f_l={f_l}")
    eps = consistency_residual(absolute_high, wrapped_low, f_h, f_l, dtype=np.float32)  # (H, W)
    if np.shape(valid) != eps.shape:
        raise ValueError(f"valid must have the phases' shape {eps.shape}; got {np.shape(valid)}")
    eps *= np.float32(1.0 / (2.0 * np.pi * delta))
    np.copyto(eps, np.float32(np.nan), where=~np.asarray(valid, dtype=bool))
    return eps


def rejected_regions(absolute_high: np.ndarray, wrapped_low: np.ndarray, f_h: float, f_l: float, valid: np.ndarray,
                     *, radius: int = DEFAULT_RADIUS, significance: float = DEFAULT_SIGNIFICANCE) -> np.ndarray:
    """Pixels ``(H, W)`` bool of the patches whose published order the low frequency rejects (module docstring).

    Parameters
    ----------
    absolute_high, wrapped_low, f_h, f_l, valid
        As :func:`order_error_estimate`'s.
    radius : int
        Half-width of the proposal window, pixels (>= 1).
    significance : float
        ``Z``, standard errors (> 0).

    Returns
    -------
    ndarray (H, W) bool
        Valid pixels of the rejected patches.
    """
    if radius < 1 or not significance > 0:
        raise ValueError(f"rejected_regions needs radius >= 1 and significance > 0; got {radius}, {significance}")
    r = order_error_estimate(absolute_high, wrapped_low, f_h, f_l, valid)
    known = np.isfinite(r)
    rejected = np.zeros(r.shape, bool)
    if np.count_nonzero(known) < 2 * MIN_TEST_PIXELS:
        return rejected
    magnitudes = r[known]
    scan_sigma = MAD_TO_SIGMA * float(bracketed_median(np.abs(magnitudes, out=magnitudes)))
    votes = np.where(known, r, np.float32(0.0))  # (H, W) float32, clipped in place
    np.maximum(votes, np.float32(-VOTE_CLIP_ORDERS), out=votes)
    np.minimum(votes, np.float32(VOTE_CLIP_ORDERS), out=votes)
    checkerboard = np.zeros(r.shape, bool)  # (H, W): row + column even
    checkerboard[0::2, 0::2] = True
    checkerboard[1::2, 1::2] = True
    first_half = known & checkerboard
    for proposing, testing in ((first_half, known & ~first_half), (known & ~first_half, first_half)):
        rejected |= _rejected_by_half(r, votes, known, proposing, testing, scan_sigma, radius, significance)
    return rejected


def _rejected_by_half(r: np.ndarray, votes: np.ndarray, known: np.ndarray, proposing: np.ndarray,
                      testing: np.ndarray, scan_sigma: float, radius: int, significance: float) -> np.ndarray:
    """The patches proposed by ``proposing``'s pixels (their clipped ``votes``) and rejected by ``testing``'s (steps
    1-2 of the module docstring)."""
    size = (2 * radius + 1, 2 * radius + 1)
    total = cv2.boxFilter(np.where(proposing, votes, np.float32(0.0)), -1, size, normalize=False,
                          borderType=cv2.BORDER_CONSTANT)
    # the count summed from uint8: whole numbers, the same float32 as a float32 map's sums
    count = cv2.boxFilter(proposing.view(np.uint8), cv2.CV_32F, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
    mean = total / np.maximum(count, np.float32(1.0))  # (H, W), orders
    rejected = np.zeros(r.shape, bool)
    for sign in (1.0, -1.0):
        candidates = known & ((mean > 0.5) if sign > 0 else (mean < -0.5))
        patches, labels = cv2.connectedComponents(candidates.view(np.uint8), connectivity=8)
        if patches <= 1:
            continue
        judged = testing & (labels > 0)
        n, median, mad = median_and_mad(r[judged], labels[judged], patches)
        sigma = np.maximum(MAD_TO_SIGMA * mad, scan_sigma)
        standard_error = _MEDIAN_SE * sigma / np.sqrt(np.maximum(n, 1))
        off = (n >= MIN_TEST_PIXELS) & (sign * median > significance * standard_error)
        off[0] = False  # the background
        rejected |= off[labels]
    return rejected & known


def median_and_mad(values: np.ndarray, labels: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per label ``0..count-1``: ``(n, median, median absolute deviation)`` of ``values``, each ``(count,)`` (0 for an
    empty label); sorted once by (label, value)."""
    n = np.bincount(labels, minlength=count)
    median = np.zeros(count)
    mad = np.zeros(count)
    if values.size == 0:
        return n, median, mad
    start = np.concatenate(([0], np.cumsum(n)[:-1]))
    low, high = start + (n - 1) // 2, start + n // 2  # the middle one or two of each label's sorted values
    present = n > 0
    low, high = np.where(present, low, 0), np.where(present, high, 0)
    order = np.lexsort((values, labels))
    values, labels = values[order], labels[order]
    median = np.where(present, 0.5 * (values[low] + values[high]), 0.0)
    deviation = np.abs(values - median[labels])
    deviation = deviation[np.lexsort((deviation, labels))]
    mad = np.where(present, 0.5 * (deviation[low] + deviation[high]), 0.0)
    return n, median, mad
