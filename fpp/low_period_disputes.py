"""Patches where two fringe orders of one capture disagree by one period of the LOW frequency: a low order chosen
wrong for a whole region.

A two-frequency method that looks the low order up (NT, Eqs. (8)-(9) of the paper) errs by one low period when its
residual lands on the wrong candidate: the high order then moves by ``f_h / f_l`` (rounded down or up, e.g. 5 or 6
for 64 / 10.9). The per-pixel lookup does so on single pixels, at random where the noise takes it across the
decision boundary: a speckle. A prior that decides one low order for a whole band of the surface (DP-TPU's NT band
prior, :mod:`dptpu.models.nt_prior`) does so on a whole patch at once, and the network and its neighbour consensus
follow it: a solid, self-consistent patch one low period off that no confidence of the network sees (on the twin of
``dptpu eval cloud``, 12 steps, 1-2 sigma: 2,420 wrong-order points, 2,190 of them where the classical lookup
disagreed by exactly one low period, in patches of 19-650 pixels).

:func:`low_period_disputes` marks the pixels where the two orders disagree by one low period and the disagreement
is solid: what survives a 3 x 3 morphological opening of the disagreement (a speckle does not: every pixel of it
would need its whole 3 x 3 neighbourhood to disagree), grown back by ``grow_px`` pixels within the disagreement
(the patch's ragged border), in connected patches of at least ``min_pixels``. Which of the two is right there is not
known (at 1-2 sigma the classical lookup's own margin is high on 14,328 pixels where it is the wrong one, so a veto by
the classical order costs completeness): the caller drops the patch (confidence 0), it shifts nothing.

Parameters and why:

- ``min_pixels`` (default :data:`DEFAULT_MIN_PIXELS` = 30): smaller solid patches are rare in a speckle and
  carried few wrong points (on the twin, components of >= 30 pixels held 2,129 of the 2,190).
- ``grow_px`` (default :data:`DEFAULT_GROW_PX` = 2): a wrong patch's border pixels agree with the reference only
  partly; 2 pixels of regrowth recover most of them without joining speckle (which the opening removed first).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

__all__ = ["DEFAULT_GROW_PX", "DEFAULT_MIN_PIXELS", "low_period_disputes"]

#: Smallest patch (connected pixels) of a solid one-low-period disagreement that is marked.
DEFAULT_MIN_PIXELS = 30
#: Pixels by which the opened core of a disagreement grows back within the disagreement.
DEFAULT_GROW_PX = 2

_SQUARE3 = np.ones((3, 3), np.uint8)


def low_period_disputes(order: np.ndarray, reference_order: np.ndarray, frequency_ratio: float,
                        valid: np.ndarray, *, min_pixels: int = DEFAULT_MIN_PIXELS,
                        grow_px: int = DEFAULT_GROW_PX) -> np.ndarray:
    """Solid patches where ``order`` and ``reference_order`` differ by one low period (module docstring).

    Parameters
    ----------
    order, reference_order : ndarray (H, W) int
        Two fringe orders of the high frequency (e.g. DP-TPU's and the classical lookup's).
    frequency_ratio : float
        ``f_h / f_l``: a low order one off moves the high order by its floor or its ceiling.
    valid : ndarray (H, W) bool
        Pixels where both orders are defined.
    min_pixels, grow_px : int
        See the module docstring.

    Returns
    -------
    ndarray (H, W) bool
        The disputed pixels.
    """
    if not (math.isfinite(frequency_ratio) and frequency_ratio > 1.0):
        raise ValueError(f"frequency_ratio must be f_h / f_l > 1; got {frequency_ratio}")
    if min_pixels < 1 or grow_px < 0:
        raise ValueError(f"min_pixels must be >= 1 and grow_px >= 0; got {min_pixels}, {grow_px}")
    a = np.asarray(order, dtype=np.int64)
    b = np.asarray(reference_order, dtype=np.int64)
    if a.shape != b.shape or a.shape != np.shape(valid) or a.ndim != 2:
        raise ValueError(f"order, reference_order and valid must be (H, W) of one shape; got {a.shape}, {b.shape}, "
                         f"{np.shape(valid)}")
    steps = np.abs(a - b)
    one_period = (steps == math.floor(frequency_ratio)) | (steps == math.ceil(frequency_ratio))
    disagree = (one_period & np.asarray(valid, dtype=bool)).astype(np.uint8)
    core = cv2.morphologyEx(disagree, cv2.MORPH_OPEN, _SQUARE3)
    if grow_px:
        core = cv2.dilate(core, np.ones((2 * grow_px + 1, 2 * grow_px + 1), np.uint8)) & disagree
    count, labels, stats, _ = cv2.connectedComponentsWithStats(core, connectivity=8)
    large = stats[:, cv2.CC_STAT_AREA] >= min_pixels
    large[0] = False  # the background
    return large[labels]
