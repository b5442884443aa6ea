"""Depth steps and the sides that continue across them (two of the depth-edge tests combined by
:func:`dptpu.fpp.depth_edges.edge_points`).

:func:`beside_steps` marks the last pixel on each side of a depth step: a neighbour (of 8) more than ``max_step``
pixel footprints ``z / f`` nearer or farther (per diagonal step ``sqrt(2) z / f``), from OpenCV's grey-level
morphologies of the depth (:func:`neighbour_steps`, shared by several thresholds through :func:`steps_beside`).
Such a pixel may integrate a sliver of the other side, whose phase is far from its own.

:func:`continues_a_side` says whether the straight continuation of two pixels of a pure side in a row, in any of
the 8 directions, predicts a pixel's depth within a tolerance: ``edge_points`` keeps a point beside a step, or a
modulation dip, that its side continues to (the module docstring of :mod:`dptpu.fpp.depth_edges` says why). Asked
at a few pixels it gathers them, at many (a steep plane beside a step everywhere) it judges the whole image, with
the same marks either way.
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = ["DEFAULT_MAX_STEP", "beside_steps", "continues_a_side", "neighbour_steps", "steps_beside"]

#: A point with a neighbour more than this many pixel footprints nearer or farther lies beside a depth step.
DEFAULT_MAX_STEP = 10.0

# the 4 side and the 4 diagonal neighbours of a pixel, as OpenCV kernels (the centre left out)
_SIDES = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], dtype=np.uint8)
_DIAGONALS = np.array([[1, 0, 1], [0, 0, 0], [1, 0, 1]], dtype=np.uint8)
#: Share of the image at or below which :func:`continues_a_side` with ``where`` gathers those pixels rather than
#: judging the whole image (the two cost the same between 10 and 50 %: docs/benchmarks.md, Run 15).
_CONTINUE_GATHER_SHARE = 0.1
# (row step, column step) of the 8 directions from a pixel
_DIRECTIONS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (-1, -1), (1, -1), (-1, 1))


def beside_steps(depth: np.ndarray, focal_px: float, *, max_step: float, side: str = "both") -> np.ndarray:
    """Pixels with a neighbour (of 8) whose depth differs by more than ``max_step`` pixel footprints ``z / f`` (per
    diagonal step ``sqrt(2) z / f``): the last pixel on each side of a depth step, (H, W) bool.

    ``side``: ``"both"``, ``"far"`` (only pixels with a NEARER neighbour that far: the far surface's last pixel) or
    ``"near"`` (only pixels with a farther one). A neighbour that far exists exactly where the nearest or the
    farthest neighbour is that far: grey-level morphologies (OpenCV, float32) over the 4 side and the 4 diagonal
    neighbours (NaN neighbours never count).
    """
    if side not in ("both", "far", "near"):
        raise ValueError(f"side must be 'both', 'far' or 'near'; got {side!r}")
    z = np.asarray(depth, dtype=np.float32)
    return steps_beside(z, neighbour_steps(z), focal_px, max_step, side)


def neighbour_steps(z: np.ndarray) -> list[tuple[np.float32, np.ndarray, np.ndarray]]:
    """``(footprint factor, farthest - z, z - nearest)`` of the 4 side and of the 4 diagonal neighbours of every
    pixel of the float32 depth ``z``: how much farther its farthest and nearer its nearest neighbour lie (OpenCV's
    grey-level dilate and erode; NaN neighbours and the outside never count: -inf), taken once for every
    threshold of :func:`steps_beside`."""
    finite = np.isfinite(z)
    nearest_fill = np.where(finite, z, np.float32(np.inf))
    farthest_fill = np.where(finite, z, np.float32(-np.inf))
    steps = []
    with np.errstate(invalid="ignore"):
        for kernel, factor in ((_SIDES, np.float32(1.0)), (_DIAGONALS, np.float32(np.sqrt(2.0)))):
            farther = cv2.dilate(farthest_fill, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=-np.inf)
            farther -= z
            nearer = cv2.erode(nearest_fill, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=np.inf)
            np.subtract(z, nearer, out=nearer)
            steps.append((factor, farther, nearer))
    return steps


def steps_beside(z: np.ndarray, steps: list[tuple[np.float32, np.ndarray, np.ndarray]], focal_px: float,
                 max_step: float, side: str) -> np.ndarray:
    """:func:`beside_steps` of the float32 depth ``z`` from its :func:`neighbour_steps` (one morphology for
    several thresholds)."""
    limit = np.float32(max_step / focal_px) * np.abs(z)  # (H, W), one side step
    out = np.zeros(z.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for factor, farther, nearer in steps:
            bound = np.multiply(factor, limit)
            if side != "far":
                out |= farther > bound
            if side != "near":
                out |= nearer > bound
    return out & np.isfinite(z)


def continues_a_side(depth: np.ndarray, pure: np.ndarray, tolerance: float,
                     where: np.ndarray | None = None) -> np.ndarray:
    """Pixels whose depth the straight continuation of two ``pure`` pixels in a row predicts within ``tolerance``,
    in any of the 8 directions: ``|z - (2 z_1 - z_2)| <= tolerance``, ``z_1``, ``z_2`` the next two pixels that way
    (the surface on that side, linearly extrapolated), (H, W) bool. ``where`` (H, W) bool: judged at those pixels
    only (False elsewhere): the same arithmetic on the pixels gathered where they are few
    (:data:`_CONTINUE_GATHER_SHARE` of the image or less), the whole image's answer there otherwise (a steep plane
    beside a step everywhere).
    """
    if where is not None:
        where = np.asarray(where, dtype=bool)
        if np.count_nonzero(where) <= _CONTINUE_GATHER_SHARE * where.size:
            return _continues_at(np.asarray(depth), np.asarray(pure, dtype=bool), tolerance, where)
        return continues_a_side(depth, pure, tolerance) & where
    z = np.asarray(depth, dtype=np.float64)
    height, width = z.shape
    padded = cv2.copyMakeBorder(np.where(pure, z, np.nan), 2, 2, 2, 2, cv2.BORDER_CONSTANT, value=np.nan)
    out = np.zeros(z.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for dr, dc in _DIRECTIONS:
            first = padded[2 + dr:2 + dr + height, 2 + dc:2 + dc + width]
            second = padded[2 + 2 * dr:2 + 2 * dr + height, 2 + 2 * dc:2 + 2 * dc + width]
            out |= np.abs(z - (2.0 * first - second)) <= tolerance
    return out


def _continues_at(depth: np.ndarray, pure: np.ndarray, tolerance: float, where: np.ndarray) -> np.ndarray:
    """:func:`continues_a_side` at the pixels of ``where`` only (float64 arithmetic on the gathered depths)."""
    height, width = depth.shape
    flat_depth, flat_pure = depth.ravel(), pure.ravel()
    pixels = np.flatnonzero(where)
    rows, cols = np.divmod(pixels, width)
    z = flat_depth[pixels].astype(np.float64)

    def pure_depth(r: np.ndarray, c: np.ndarray) -> np.ndarray:  # the pure pixels' depth, NaN elsewhere and outside
        inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
        index = np.where(inside, r * width + c, 0)  # (not numpy's clip: its checks cost more than the arithmetic)
        return np.where(inside & flat_pure[index], flat_depth[index].astype(np.float64), np.nan)

    steps = np.array(_DIRECTIONS)  # (8, 2): the 8 directions at once, (M, 8) gathers
    first = pure_depth(rows[:, None] + steps[:, 0], cols[:, None] + steps[:, 1])
    second = pure_depth(rows[:, None] + 2 * steps[:, 0], cols[:, None] + 2 * steps[:, 1])
    with np.errstate(invalid="ignore"):
        hit = (np.abs(z[:, None] - (2.0 * first - second)) <= tolerance).any(axis=1)
    out = np.zeros(depth.shape, dtype=bool)
    np.put(out, pixels[hit], True)
    return out
