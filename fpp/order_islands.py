"""Islands of a wrong fringe order: regions whole orders off from the surface around them, found in the phase alone.

A wrong fringe order rarely comes alone. Where the temporal prior is weak (low modulation, the low frequency's noise
amplified ``f_h / f_l`` times), DP-TPU and the classical methods alike put a whole patch of a surface one order (or
more) off, and the network's neighbour consensus makes the patch self-consistent: every pixel of it agrees with its
neighbours, its own margin and its prior can both be high, and the confidence of :mod:`dptpu.fpp.confidence` does
not see it. Its border does: the absolute phase ``Phi`` of a smooth surface changes by less than ``pi`` between
neighbouring pixels (the condition of spatial unwrapping, Itoh's), so a patch whole orders off meets the surface
around it with a jump of ``2 pi s`` (give or take that small change, ``s`` its order error) all along its border,
while the fringe modulation runs on unbroken across it, as on any smooth surface.

:func:`order_islands` finds such patches:

1. **Regions.** Neighbouring valid pixels (4-connected) are linked where ``|Phi_b - Phi_a| < pi``; the connected
   components of these links are the order-consistent regions (OpenCV's connected components on a grid of pixels
   and links).
2. **Borders.** Each unlinked neighbour pair joins two regions; ``s = Round((Phi_R - Phi_Q) / 2 pi)`` is the order
   step of the pair, ``R`` the smaller region. A pair is *smooth* where neither pixel's modulation ``B`` dips below
   ``min_modulation_ratio`` times the brightest modulation within two pixels: at an occlusion the two surfaces'
   phasors mix and ``B`` dips, and the phase jump there is any value.
3. **Islands.** A region ``R`` is an island where, towards some larger region ``Q``, at least ``min_pairs`` border
   pairs and a share ``min_share`` of all their border pairs are smooth with one and the same step ``s != 0``:
   ``R`` is a patch of ``Q``'s surface ``s`` orders off. The smaller side is the one called wrong, and it is dropped,
   not shifted: a depth step that happens to be one fringe period deep would look the same, and a dropped patch
   costs completeness where a shifted one could cost precision.

A real depth step between two surfaces looks like an island border where the step is about the same whole number
of periods deep along its whole length and the surfaces' modulation does not dip at the edge: an object before a
plane, its face parallel to the plane, can. The share and the modulation test keep such borders rare, and
``max_island_share`` keeps whole objects out: a wrong-order patch is a small part of a surface, an object seen whole
is not (``docs/nodes.md``, "Order islands", has the measurements). The rule uses no length, focal length, frequency
or noise level: only the phase's own ``2 pi``, the modulation's ratio and a share of the image.

Parameters and why:

- ``min_share`` (default :data:`DEFAULT_MIN_SHARE` = 0.8): an island's border is ``s`` orders off on (nearly)
  every pair; an occlusion's phase jump varies along the edge. The fifth of the pairs left over is for the noisy
  and mixed pixels of a border.
- ``min_pairs`` (default :data:`DEFAULT_MIN_PAIRS` = 3): a lone wrong pixel has four border pairs; fewer than
  three agreeing pairs are too few to call a border.
- ``max_island_share`` (default :data:`DEFAULT_MAX_ISLAND_SHARE` = 0.01): no region of more than 1 % of the valid
  pixels is an island. The network's wrong patches on the shipped Blender scenes held 0.1-0.6 % of a scan's pixels;
  the objects of the outside rigs' scenes whose border with the background plane looked like an island's held
  1.4-20 %.
- ``min_modulation_ratio`` (default :data:`DEFAULT_MIN_MODULATION_RATIO` = 0.5): a mixed pixel at an occlusion
  keeps less than half of its brighter neighbour's modulation (two phasors of random relative phase); noise and
  shading change ``B`` by far less between neighbours.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["DEFAULT_MAX_ISLAND_SHARE", "DEFAULT_MIN_MODULATION_RATIO", "DEFAULT_MIN_PAIRS", "DEFAULT_MIN_SHARE",
           "OrderIslands", "order_islands"]

#: Share of a border's pairs that must be smooth with one common nonzero order step.
DEFAULT_MIN_SHARE = 0.8
#: A region holding more than this share of the valid pixels is never called an island.
DEFAULT_MAX_ISLAND_SHARE = 0.01
#: Border pairs needed to call a region an island.
DEFAULT_MIN_PAIRS = 3
#: A border pair is smooth where both pixels keep this fraction of the brightest modulation within two pixels.
DEFAULT_MIN_MODULATION_RATIO = 0.5

_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class OrderIslands:
    """What :func:`order_islands` found.

    Attributes
    ----------
    islands : ndarray (H, W) bool
        Valid pixels in a region whole orders off from a larger neighbouring region.
    step : ndarray (H, W) int8
        The island's order minus its neighbour's, as its border says (0 off the islands): the island's order
        would be right if lowered by ``step``.
    regions : int
        Order-consistent regions among the valid pixels.
    island_regions : int
        Regions called islands.
    """

    islands: np.ndarray
    step: np.ndarray
    regions: int
    island_regions: int


def _order_regions(phi: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Order-consistent regions and the broken neighbour pairs between them.

    The pixel grid is drawn at twice its resolution: pixel ``(r, c)`` at ``(2r, 2c)``, the link to its right
    neighbour at ``(2r, 2c + 1)``, to the one below at ``(2r + 1, 2c)``, each set where both pixels are valid and
    ``|Phi_b - Phi_a| < pi``; OpenCV's 4-connected components of that grid are exactly the components of the links.

    Returns
    -------
    labels : ndarray (H, W) int32
        Region of each pixel, 0 where not valid.
    a, b : ndarray (P,) int64
        Flat indices of the valid neighbour pairs whose link is broken (``|Phi_b - Phi_a| >= pi``).
    difference : ndarray (P,) float64
        ``Phi_b - Phi_a`` of those pairs.
    """
    height, width = phi.shape
    pair_right = valid[:, 1:] & valid[:, :-1]
    pair_down = valid[1:, :] & valid[:-1, :]
    link_right = _linked(phi[:, 1:], phi[:, :-1])  # (H, W-1)
    link_right &= pair_right
    link_down = _linked(phi[1:, :], phi[:-1, :])  # (H-1, W)
    link_down &= pair_down
    grid = np.zeros((2 * height - 1, 2 * width - 1), dtype=np.uint8)
    grid[::2, ::2] = valid
    grid[::2, 1::2] = link_right
    grid[1::2, ::2] = link_down
    np.logical_xor(pair_right, link_right, out=pair_right)  # the valid pairs whose link is broken
    np.logical_xor(pair_down, link_down, out=pair_down)
    _, grid_labels = cv2.connectedComponents(grid, connectivity=4, ltype=cv2.CV_32S)
    labels = np.ascontiguousarray(grid_labels[::2, ::2])
    # the broken pairs in row-major order, from flat indices (numpy's 2-D nonzero scans ~20 times slower): a right
    # pair's flat index f in the (H, W - 1) image is pixel f + f // (W - 1) of the (H, W) one, a down pair's is f
    broken_right = np.flatnonzero(pair_right)
    broken_down = np.flatnonzero(pair_down)
    left_pixel = broken_right + broken_right // (width - 1)
    a = np.concatenate([left_pixel, broken_down]).astype(np.int64)
    b = np.concatenate([left_pixel + 1, broken_down + width]).astype(np.int64)
    flat = phi.ravel()
    difference = np.subtract(flat[b], flat[a], dtype=np.float64)  # in float64 whatever phi's dtype
    return labels, a, b, difference


#: ``|d| < pi`` is decided in float32 outside ``[_BELOW_PI, _ABOVE_PI]`` (float32 roundings of ``pi (1 -+ 2^-21)``).
_BELOW_PI = np.float32(np.pi * (1.0 - 2.0 ** -21))
_ABOVE_PI = np.float32(np.pi * (1.0 + 2.0 ** -21))


def _linked(after: np.ndarray, before: np.ndarray) -> np.ndarray:
    """``|after - before| < pi`` with the difference in float64 (a float32 difference could round across pi), (same
    shape) bool; NaN never links.

    A float32 phase's difference is taken in float32 first: float32 and float64 subtraction each round the same
    exact difference ``D`` of two float32 values correctly, so where the float32 one lies below ``pi (1 - 2^-21)``
    (``|D| < pi (1 - 2^-22)``) or above ``pi (1 + 2^-21)`` (``|D| > pi (1 + 2^-22)``) the float64 one is on the same
    side of pi; the few in between are taken again in float64. Half the memory traffic of float64 differences, the
    same links."""
    with np.errstate(invalid="ignore", over="ignore"):
        if after.dtype != np.float32:
            return np.abs(np.subtract(after, before, dtype=np.float64)) < np.pi
        difference = np.subtract(after, before)
        np.abs(difference, out=difference)
        linked = difference < _BELOW_PI
        close = np.flatnonzero((difference <= _ABOVE_PI) & ~linked)  # within float32 rounding of pi: float64
        if close.size:
            rows, cols = np.divmod(close, after.shape[1])
            exact = np.abs(np.subtract(after[rows, cols], before[rows, cols], dtype=np.float64)) < np.pi
            linked.ravel()[close] = exact
    return linked


#: The 5 x 5 window within two pixels, as (row, column) offsets.
_WITHIN_TWO = np.stack(np.meshgrid(np.arange(-2, 3), np.arange(-2, 3), indexing="ij")).reshape(2, -1)  # (2, 25)


class _ValidModulation:
    """The map ``np.nan_to_num(B)`` where ``valid``, 0 elsewhere (H, W) float32, read at a few flat pixel indices:
    the broken pairs' pixels and their 5 x 5 windows (making the whole map and dilating it cost more than the pairs'
    windows; nan_to_num and max are exact, so the values are the whole map's and its dilation's)."""

    def __init__(self, modulation: np.ndarray, valid: np.ndarray) -> None:
        self.modulation, self.valid = modulation.ravel(), valid.ravel()
        self.height, self.width = modulation.shape

    def at(self, pixels: np.ndarray) -> np.ndarray:
        """The map at the flat indices ``pixels`` (any shape)."""
        return np.where(self.valid[pixels], np.nan_to_num(self.modulation[pixels]), np.float32(0.0))

    def brightest_near(self, pixels: np.ndarray) -> np.ndarray:
        """The largest value of the map within two pixels (the 5 x 5 window, inside the image) of each flat index
        ``pixels`` (M,): its grey-level dilation by a 5 x 5 square (``cv2.dilate``) there."""
        rows, cols = np.divmod(pixels, self.width)
        r = rows[:, None] + _WITHIN_TWO[0]  # (M, 25)
        c = cols[:, None] + _WITHIN_TWO[1]
        inside = (r >= 0) & (r < self.height) & (c >= 0) & (c < self.width)
        window = self.at(np.where(inside, r * self.width + c, 0))
        return np.where(inside, window, np.float32(-np.inf)).max(axis=1, initial=-np.inf)


def order_islands(absolute_phase: np.ndarray, modulation: np.ndarray, valid: np.ndarray, *,
                  min_share: float = DEFAULT_MIN_SHARE, min_pairs: int = DEFAULT_MIN_PAIRS,
                  min_modulation_ratio: float = DEFAULT_MIN_MODULATION_RATIO,
                  max_island_share: float = DEFAULT_MAX_ISLAND_SHARE) -> OrderIslands:
    """Regions of ``absolute_phase`` whole fringe orders off from a larger neighbouring region (module docstring).

    Parameters
    ----------
    absolute_phase : ndarray (H, W)
        ``Phi`` in radians (Eq. (3)); read where ``valid`` only.
    modulation : ndarray (H, W)
        Fringe modulation ``B`` of the same sequence, any intensity unit.
    valid : ndarray (H, W) bool
        Pixels with an order (e.g. after the confidence threshold).
    min_share, min_pairs, min_modulation_ratio
        See the module docstring.
    """
    phi = np.asarray(absolute_phase)
    if not np.issubdtype(phi.dtype, np.floating):
        phi = phi.astype(np.float64)
    valid = np.asarray(valid, dtype=bool) & np.isfinite(phi)
    if phi.ndim != 2 or phi.shape != valid.shape or np.shape(modulation) != phi.shape:
        raise ValueError(f"absolute_phase, modulation and valid must be (H, W) of one shape; got {phi.shape}, "
                         f"{np.shape(modulation)}, {valid.shape}")
    if not (0.0 < min_share <= 1.0 and min_pairs >= 1 and 0.0 <= min_modulation_ratio <= 1.0
            and 0.0 < max_island_share <= 1.0):
        raise ValueError(f"need 0 < min_share <= 1, min_pairs >= 1, 0 <= min_modulation_ratio <= 1, "
                         f"0 < max_island_share <= 1; got {min_share}, {min_pairs}, {min_modulation_ratio}, "
                         f"{max_island_share}")
    label_image, a, b, difference = _order_regions(phi, valid)
    labels = label_image.ravel()
    sizes = np.bincount(labels).astype(np.float64)
    sizes[0] = 0.0  # label 0: the pixels without an order
    region_count = int(np.count_nonzero(sizes))

    # the border pairs, each seen from its smaller region R towards the larger Q
    label_a, label_b = labels[a], labels[b]
    a_smaller = sizes[label_a] < sizes[label_b]
    small = np.where(a_smaller, label_a, label_b)
    large = np.where(a_smaller, label_b, label_a)
    step = np.rint(np.where(a_smaller, -difference, difference) / _TWO_PI)  # order of R minus order of Q
    unequal = (sizes[small] < sizes[large]) & (sizes[small] <= max_island_share * np.count_nonzero(valid))

    # the modulation map the test reads, B (NaN as 0) where valid and 0 elsewhere, taken at the pairs' pixels and
    # their windows only
    b_map = _ValidModulation(np.asarray(modulation, dtype=np.float32), valid)
    with np.errstate(invalid="ignore", divide="ignore"):
        smooth = np.minimum(b_map.at(a), b_map.at(b)) >= min_modulation_ratio * np.maximum(b_map.brightest_near(a),
                                                                                          b_map.brightest_near(b))

    # per border (R, Q): all its pairs, and the most common nonzero step among its smooth pairs
    key = small.astype(np.int64) * labels.size + large.astype(np.int64)
    border, border_index = np.unique(key[unequal], return_inverse=True)
    total = np.bincount(border_index, minlength=border.size)
    candidate = (smooth & (step != 0))[unequal]
    stepped = np.stack([border_index[candidate], step[unequal][candidate].astype(np.int64)], axis=1)
    agreeing = np.zeros(border.size, dtype=np.int64)
    border_step = np.zeros(border.size, dtype=np.int64)
    if stepped.size:
        pair, count = np.unique(stepped, axis=0, return_counts=True)  # (border, step) rows, sorted by border
        order = np.lexsort((count, pair[:, 0]))
        last = np.r_[np.flatnonzero(np.diff(pair[order, 0])), order.size - 1]  # each border's most common step
        agreeing[pair[order[last], 0]] = count[order[last]]
        border_step[pair[order[last], 0]] = pair[order[last], 1]
    island_border = np.flatnonzero((agreeing >= min_pairs) & (agreeing >= min_share * total))
    # a region with several island borders takes the step of its longest one
    island_region = border[island_border] // labels.size
    longest = np.zeros(sizes.size, dtype=np.int64)
    np.maximum.at(longest, island_region, agreeing[island_border])
    chosen = agreeing[island_border] == longest[island_region]
    region_step = np.zeros(sizes.size, dtype=np.int64)
    region_step[island_region[chosen]] = border_step[island_border[chosen]]
    if region_step.any():
        island_step = region_step[label_image].astype(np.int8)  # label 0 (no order) never has a step
    else:  # no island (a clean scan): no gather over the image
        island_step = np.zeros(label_image.shape, dtype=np.int8)
    islands = island_step != 0
    return OrderIslands(islands=islands, step=island_step, regions=region_count,
                        island_regions=int(np.count_nonzero(region_step)))
