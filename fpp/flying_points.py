"""Flying points: pixels whose depth stands apart from both neighbours along a line, and the straight-ramp test
that keeps a steep plane's pixels (one of the depth-edge tests combined by :func:`dptpu.fpp.depth_edges.edge_points`).

:func:`flying_points` marks a pixel whose depth differs from BOTH its neighbours along a line (left and right, up
and down, or either diagonal) by more than ``max_slope`` times the pixel's footprint ``z / f`` (the lateral
distance one pixel spans at depth ``z``, per diagonal step ``sqrt(2) z / f``). The ratio is the tangent of the
angle between the surface and the image plane, so the rule does not depend on the rig's focal length, working
distance or units. A pixel on a smooth surface, however tilted up to ``atan(max_slope)``, is never marked; the
last pixel of a foreground surface has one neighbour on the same surface, so it is kept; a mixed pixel between the
two sides (or a sliver of them) differs from both and is marked. Invalid (NaN) neighbours never mark a pixel (the
background behind a projector shadow carries no phase, so a pixel mixing the foreground with a shadow keeps the
foreground's phase).

A pixel on a plane steeper than ``atan(max_slope)`` also differs from both neighbours, by the same step on each
side: it is kept where the five pixels of the line through it (two on each side) are straight, every second
difference ``|z_{i-1} - 2 z_i + z_{i+1}|`` at most ``max_ramp_bend`` times the mean step ``|z_after - z_before| / 2``
(:func:`on_a_ramp`). Its phase is right: a pixel integrates a phase that changes linearly over its area, whose mean
is the phase at its centre. A mixed pixel is never so: with a fraction ``w`` of the far side, a step ``dz`` between
two flat sides gives the line ``0, 0, w dz, dz, dz``, whose second differences ``w dz``, ``(1 - 2 w) dz`` and
``(1 - w) dz`` reach at least the mean step ``dz / 2`` for any ``w`` (a bend ratio of 1, four times the default).
On the outside tester's cluttered scene (f 1500 px, 320x240) the crate's top face, 79 degrees from facing the
camera, went as "flying" in whole (327 of the 330 flying points dropped there lay within 1 mm of the truth).

The straight-ramp test is gathered at the apart pixels where those are few and run on the whole image where many
ask (a steep plane), with the same marks either way.

Parameters and why (``docs/nodes.md``, "Flying points", has the measurements behind the defaults):

- ``max_slope`` (default :data:`DEFAULT_MAX_SLOPE` = 4, a surface inclined ``atan(4) = 76`` degrees from facing
  the camera): a mixed pixel at an edge of depth step ``dz`` differs from its two neighbours by about ``dz / 2``,
  i.e. by ``f dz / (2 z)`` footprints, more than 4 for any step over 8 footprints (8 mm at a 1 mm footprint).
- ``max_ramp_bend`` (default :data:`DEFAULT_MAX_RAMP_BEND` = 0.25): a mixed pixel's line bends by at least the
  mean step (ratio 1, above); depth noise bends a steep plane's line by ``sqrt(6) sigma_z``, a quarter of a step of
  ``max_slope`` = 4 footprints where ``sigma_z`` is 0.4 footprints (0.7 mm at the outside tester's 1.77 mm
  footprint; its 12-step 1 sigma scan has ~0.3 mm); noisier planes stay dropped.
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = ["DEFAULT_MAX_RAMP_BEND", "DEFAULT_MAX_SLOPE", "flying_points", "on_a_ramp"]

#: Depth change between neighbouring pixels, in pixel footprints ``z / f``, above which a pixel that differs so from
#: both its neighbours along a line is a flying point: the tangent of the steepest surface kept (76 degrees).
DEFAULT_MAX_SLOPE = 4.0
#: Largest second difference along a line of five pixels, as a share of the mean step between the middle pixel's
#: neighbours, of a steep plane (a ramp) whose pixels are not flying points.
DEFAULT_MAX_RAMP_BEND = 0.25
# (row step, column step, footprint factor) of the four lines through a pixel
_LINES = ((0, 1, 1.0), (1, 0, 1.0), (1, 1, np.sqrt(2.0)), (1, -1, np.sqrt(2.0)))
#: Share of the image at or below which :func:`flying_points` judges a line's apart pixels' ramp at those pixels
#: (gathered) rather than on the whole image (the two cost the same near 3 %: docs/benchmarks.md, Run 15).
_RAMP_GATHER_SHARE = 0.03


def flying_points(depth: np.ndarray, focal_px: float, *, max_slope: float = DEFAULT_MAX_SLOPE,
                  max_ramp_bend: float = DEFAULT_MAX_RAMP_BEND) -> np.ndarray:
    """Pixels whose depth stands apart from both neighbours along a line and do not lie on a straight ramp
    through them (see the module docstring).

    Parameters
    ----------
    depth : ndarray (H, W)
        Depth ``z`` along the camera axis (any unit), NaN where there is no point.
    focal_px : float
        The camera's focal length in pixels (``K[0, 0]``; the mean of ``fx`` and ``fy`` for non-square pixels).
    max_slope : float
        Depth change per neighbour step, in pixel footprints ``z / focal_px``, above which a neighbour is apart.
    max_ramp_bend : float
        :func:`on_a_ramp`'s bound: a pixel apart from both neighbours along a line whose five pixels bend less is on
        a steep plane, kept; 0 marks every such pixel (no ramp is straight enough).

    Returns
    -------
    ndarray (H, W) bool
        True at flying points (never where ``depth`` is NaN).
    """
    if not (np.isfinite(focal_px) and focal_px > 0):
        raise ValueError(f"focal_px must be a positive number of pixels; got {focal_px}")
    if not (np.isfinite(max_slope) and max_slope > 0):
        raise ValueError(f"max_slope must be > 0 (a depth change in pixel footprints); got {max_slope}")
    if not (np.isfinite(max_ramp_bend) and max_ramp_bend >= 0):
        raise ValueError(f"max_ramp_bend must be >= 0 (a share of the mean step); got {max_ramp_bend}")
    z = np.asarray(depth, dtype=np.float32)
    if z.ndim != 2:
        raise ValueError(f"depth must be an (H, W) image; got shape {z.shape}")
    padded = cv2.copyMakeBorder(z, 2, 2, 2, 2, cv2.BORDER_CONSTANT, value=np.nan)  # two pixels: the ramp's line
    height, width = z.shape
    footprint = np.abs(z) * np.float32(1.0 / focal_px)  # (H, W) lateral extent of one pixel at its depth
    flying = np.zeros(z.shape, dtype=bool)
    # buffers reused over the lines; cv2.absdiff is |a - b| in one float32 pass (numpy's abs of the difference, bit
    # for bit)
    limit, step_before, step_after = np.empty_like(z), np.empty_like(z), np.empty_like(z)
    apart_before, apart_after = np.empty(z.shape, dtype=bool), np.empty(z.shape, dtype=bool)
    ramp = _RampTest(padded, max_ramp_bend) if max_ramp_bend > 0 else None
    with np.errstate(invalid="ignore"):  # NaN comparisons are False: no point, no mark
        for dr, dc, factor in _LINES:
            before = padded[2 - dr:2 - dr + height, 2 - dc:2 - dc + width]
            after = padded[2 + dr:2 + dr + height, 2 + dc:2 + dc + width]
            np.multiply(np.float32(max_slope * factor), footprint, out=limit)
            cv2.absdiff(z, before, dst=step_before)
            cv2.absdiff(after, z, dst=step_after)
            np.greater(step_before, limit, out=apart_before)
            np.greater(step_after, limit, out=apart_after)
            apart_before &= apart_after
            if ramp is not None:
                ramp.clear(apart_before, dr, dc)
            flying |= apart_before
    return flying


class _RampTest:
    """:func:`on_a_ramp` of the pixels apart on a line, with the same marks bit for bit: gathered at those pixels
    when they are few (:data:`_RAMP_GATHER_SHARE` of the image or less; a scene's edges), else on the whole image at
    once (a steep plane, where most pixels are apart): the line's absolute second differences ``|z_{k-1} - 2 z_k +
    z_{k+1}|`` of every pixel and its ring in one float64 pass each (numpy's order of operations, as
    :func:`on_a_ramp`), their largest over the three centred on ``k = -1, 0, 1`` (a NaN among them stays NaN: no
    ramp) against ``max_bend * |z_1 - z_-1| / 2``. Buffers are reused over the four lines."""

    def __init__(self, padded: np.ndarray, max_bend: float) -> None:
        self.padded, self.max_bend = padded, max_bend  # float32 depth with two pixels of NaN around it
        self.height, self.width = padded.shape[0] - 4, padded.shape[1] - 4
        self.padded64: np.ndarray | None = None  # allocated at the first whole-image line

    def clear(self, apart: np.ndarray, dr: int, dc: int) -> None:
        """Set ``apart`` (H, W) bool False at its pixels that lie on a straight ramp along the line ``(dr, dc)``."""
        count = np.count_nonzero(apart)
        if count == 0:
            return
        if count <= _RAMP_GATHER_SHARE * apart.size:
            pixels = np.flatnonzero(apart)  # (numpy's 2-D nonzero scans the image ~20 times slower)
            # the line's five pixels in the padded image (two pixels of NaN around: always inside it), as on_a_ramp
            # reads them
            padded_width = self.width + 4
            centre = pixels + (pixels // self.width) * 4 + 2 * padded_width + 2
            step = dr * padded_width + dc
            flat = self.padded.ravel()
            line = [flat[centre + k * step].astype(np.float64) for k in (-2, -1, 0, 1, 2)]
            np.put(apart, pixels[_straight(line, self.max_bend)], False)
            return
        height, width = self.height, self.width
        if self.padded64 is None:
            self.padded64 = self.padded.astype(np.float64)
            self.bend = np.empty((height + 2, width + 2))  # second differences of the image and its 1-pixel ring
            self.worst, self.bound = np.empty((height, width)), np.empty((height, width))
            self.straight = np.empty((height, width), dtype=bool)
        z, bend, worst, bound = self.padded64, self.bend, self.worst, self.bound
        np.multiply(z[1:height + 3, 1:width + 3], 2.0, out=bend)  # on_a_ramp's z_{k-1} - 2 z_k + z_{k+1}, in order
        np.subtract(z[1 - dr:height + 3 - dr, 1 - dc:width + 3 - dc], bend, out=bend)
        np.add(bend, z[1 + dr:height + 3 + dr, 1 + dc:width + 3 + dc], out=bend)
        np.abs(bend, out=bend)
        np.maximum(bend[1 - dr:height + 1 - dr, 1 - dc:width + 1 - dc], bend[1:height + 1, 1:width + 1], out=worst)
        np.maximum(worst, bend[1 + dr:height + 1 + dr, 1 + dc:width + 1 + dc], out=worst)
        np.subtract(z[2 + dr:height + 2 + dr, 2 + dc:width + 2 + dc], z[2 - dr:height + 2 - dr, 2 - dc:width + 2 - dc],
                    out=bound)
        np.abs(bound, out=bound)
        np.multiply(bound, self.max_bend * 0.5, out=bound)  # on_a_ramp's max_bend * 0.5 * |z_1 - z_-1|
        with np.errstate(invalid="ignore"):
            np.less_equal(worst, bound, out=self.straight)
        apart &= ~self.straight


def on_a_ramp(depth: np.ndarray, rows: np.ndarray, cols: np.ndarray, dr: int, dc: int,
              max_bend: float = DEFAULT_MAX_RAMP_BEND) -> np.ndarray:
    """Whether the pixels ``(rows, cols)`` lie on a straight ramp along the line ``(dr, dc)``, (M,) bool.

    The line's five depths ``z_-2 .. z_2`` (two pixels each way; a NaN or a pixel outside the image: not a ramp)
    have every second difference ``|z_{i-1} - 2 z_i + z_{i+1}|``, ``i = -1, 0, 1``, at most
    ``max_bend * |z_1 - z_-1| / 2`` (float64 arithmetic).

    Parameters
    ----------
    depth : ndarray (H, W)
        Depth, NaN where there is no point.
    rows, cols : ndarray (M,) int
        The pixels judged.
    dr, dc : int
        The line's step (row, column): (0, 1), (1, 0), (1, 1) or (1, -1).
    max_bend : float
        Largest second difference as a share of the mean step.
    """
    z = np.asarray(depth)
    height, width = z.shape
    flat = z.ravel()

    def at(k: int) -> np.ndarray:  # z_k, NaN outside the image (flat indices: numpy's clip costs more per call)
        r, c = rows + k * dr, cols + k * dc
        inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
        return np.where(inside, flat[np.where(inside, r * width + c, 0)].astype(np.float64), np.nan)

    return _straight([at(k) for k in (-2, -1, 0, 1, 2)], max_bend)


def _straight(line: list[np.ndarray], max_bend: float) -> np.ndarray:
    """:func:`on_a_ramp` of the five float64 depths ``z_-2 .. z_2`` (M,) each of a line (NaN: not a ramp)."""
    limit = max_bend * 0.5 * np.abs(line[3] - line[1])
    ramp = np.ones(line[0].shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for i in (1, 2, 3):
            ramp &= np.abs(line[i - 1] - 2.0 * line[i] + line[i + 1]) <= limit
    return ramp
