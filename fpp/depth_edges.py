"""Flying points at depth edges: mixed pixels found from the geometry and from the fringes' own modulation.

A camera pixel that straddles a depth edge integrates foreground and background; its fringe phase is a blend of
the two (the sum of two phasors), so it triangulates to a point between the surfaces, or anywhere when the two
phases nearly cancel: a "flying point". A surface seen edge-on (its normal almost perpendicular to the camera ray)
gives points whose depth changes by many pixel footprints from one pixel to the next: kept where that change runs
on straight over five pixels (a plane, measured right), dropped where it bends (a corner or a limb).

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

Four more signs of a pixel that straddles an edge, all used by :func:`edge_points`:

- a neighbour more than ``max_step`` footprints nearer or farther (:func:`beside_steps`): the last pixel on each
  side of a depth step (a step, not a slope: 10 footprints between neighbours is a surface 84 degrees from facing
  the camera) may integrate a sliver of the other side, whose phase is far from its own. The flying points are
  taken out first: a lone wrong point is flying, and its right neighbours are not beside a step. Such a point is
  kept where its modulation does not dip (below) and a pure side continues to it within ``max_edge_error / 2``
  (:func:`continues_a_side`): a sliver of the other side adds a phasor of another phase, which lowers the
  modulation, and moves the phase, which takes the point off its side's line; a pixel that shows neither lies on
  its side's surface within the tolerance (a band one order off beside a step, which continued itself on the main
  job's random-1 when the side's continuation alone kept a point, 0.054 -> 0.186 % wrong on an older tree, is
  caught by the islands and the confidence now: the main job's configuration offline, MW 64/63, the network
  without its consensus, random-1 0.036 -> 0.041 % wrong at 91.78 -> 92.59 % complete);
- its fringe modulation ``B`` dips below ``min_modulation_ratio`` times the largest of its 8 neighbours' AND it lies
  at a depth edge (within one pixel of a pixel with a neighbour more than ``max_slope`` footprints away) or beside an
  unlit pixel: the phasors of two surfaces (or of a lit surface and a projector shadow) add to less than either. A
  dip on a smooth surface is an albedo (texture) edge, whose phase is right: kept; so is a dip (not beside an unlit
  pixel) that a pure side continues to within ``max_edge_error / 2`` (:func:`continues_a_side`);
- beside an unlit pixel (a projector shadow), a ``shadow_border`` point whose lit fraction ``r = B / B_max`` (of its
  8 neighbours) is below :data:`MIN_LIT_FRACTION` (its centre lies in the shadow) or whose predicted depth error
  exceeds ``max_edge_error``: a partly shadowed pixel carries the phase of its lit part only, whose centre lies
  ``(1 - r) / 2`` pixels off the pixel's centre, across the shadow's border; the part of that offset along the
  fringe axis (``|cos|`` of the border normal's angle to it) times :func:`depth_per_pixel`, the depth change along
  the pixel's ray when its projector coordinate moves by one camera pixel's worth of fringe, is its depth error (a
  narrow baseline makes it large: 5 degrees, ~10 mm per pixel on the twin's f1300 rig; 20 degrees, ~1 mm);
- it has fewer than ``min_neighbours`` of its 8 neighbours left with a point: a sliver between edges or shadows,
  which no neighbour confirms.

An albedo edge at a depth edge or a shadow also dips the modulation; its pixels are dropped though their depth is
right (completeness, never precision, pays for it).

The tests that concern a few pixels are computed at those pixels only, each with the arithmetic it has on the whole
image (the same marks bit for bit): the lit fraction and the predicted error of the pixels beside an unlit one
(``depth_per_px`` as a callable: the second triangulation of :func:`depth_per_pixel` at those pixels), the
continuation of a side at the dips it could keep. The straight-ramp test and the continuation beside a step are
gathered at their pixels where those are few and run on the whole image where many ask (a steep plane), with the
same marks either way.

Parameters and why (``docs/nodes.md``, "Flying points", has the measurements behind the defaults):

- ``max_slope`` (default :data:`DEFAULT_MAX_SLOPE` = 4, a surface inclined ``atan(4) = 76`` degrees from facing
  the camera): a mixed pixel at an edge of depth step ``dz`` differs from its two neighbours by about ``dz / 2``,
  i.e. by ``f dz / (2 z)`` footprints, more than 4 for any step over 8 footprints (8 mm at a 1 mm footprint).
- ``max_ramp_bend`` (default :data:`DEFAULT_MAX_RAMP_BEND` = 0.25): a mixed pixel's line bends by at least the
  mean step (ratio 1, above); depth noise bends a steep plane's line by ``sqrt(6) sigma_z``, a quarter of a step of
  ``max_slope`` = 4 footprints where ``sigma_z`` is 0.4 footprints (0.7 mm at the outside tester's 1.77 mm
  footprint; its 12-step 1 sigma scan has ~0.3 mm); noisier planes stay dropped.
- ``max_step`` (default :data:`DEFAULT_MAX_STEP` = 10): on the twin's outside-rig scenes the last pixel beside a
  step held half of what stayed off the surface; those its side continues to without a dip are kept (above).
- ``min_modulation_ratio`` (default :data:`DEFAULT_MIN_MODULATION_RATIO` = 0.6): a pixel at 60 % of its brightest
  neighbour's modulation; noise and smooth shading change ``B`` by a few percent between neighbours, texture by more
  (0.7 halves what stays off the surface again but costs about 0.7 % of completeness on textured scenes; at 0.8 the
  noise of 3-step captures starts to trigger it).
- ``max_edge_error`` (depth units; ``dptpu triangulate``, the cloud node and ``dptpu eval cloud`` pass
  :data:`DEFAULT_MAX_EDGE_ERROR_MM` = 1 mm in the rig's unit, the off-surface bound of ``dptpu eval cloud``; None
  turns the predicted-error test and the continuation off).
- ``min_neighbours`` (default :data:`DEFAULT_MIN_NEIGHBOURS` = 2).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from .bracketed_median import bracketed_median

__all__ = ["DEFAULT_MAX_EDGE_ERROR_MM", "DEFAULT_MAX_RAMP_BEND", "DEFAULT_MAX_SLOPE", "DEFAULT_MAX_STEP",
           "DEFAULT_MIN_MODULATION_RATIO", "DEFAULT_MIN_NEIGHBOURS", "MIN_LIT_FRACTION", "EdgePoints", "beside_steps",
           "continues_a_side", "depth_per_pixel", "edge_points", "flying_points", "on_a_ramp"]

#: Depth change between neighbouring pixels, in pixel footprints ``z / f``, above which a pixel that differs so from
#: both its neighbours along a line is a flying point: the tangent of the steepest surface kept (76 degrees).
DEFAULT_MAX_SLOPE = 4.0
#: Largest second difference along a line of five pixels, as a share of the mean step between the middle pixel's
#: neighbours, of a steep plane (a ramp) whose pixels are not flying points.
DEFAULT_MAX_RAMP_BEND = 0.25
#: A pixel whose modulation is below this fraction of its brightest 8-neighbour's is a mixed pixel.
DEFAULT_MIN_MODULATION_RATIO = 0.6
#: A point with fewer of its 8 neighbours holding a point is a sliver.
DEFAULT_MIN_NEIGHBOURS = 2
#: A point with a neighbour more than this many pixel footprints nearer or farther lies beside a depth step.
DEFAULT_MAX_STEP = 10.0
#: Largest depth error of a point kept at an edge (predicted for a partly shadowed one; a modulation dip is kept
#: where a pure side continues to it within half of it), millimetres: convert to the depth's unit.
DEFAULT_MAX_EDGE_ERROR_MM = 1.0
#: A point beside an unlit pixel whose modulation is below this fraction of its brightest neighbour's has its centre
#: in the shadow: no surface there is lit (``dptpu eval cloud`` counts such a point as having no true surface).
MIN_LIT_FRACTION = 0.5

# the 8 neighbours, the 4 side ones and the 4 diagonal ones of a pixel, as OpenCV kernels (the centre left out)
_NEIGHBOURS = np.array([[1, 1, 1], [1, 0, 1], [1, 1, 1]], dtype=np.uint8)
_SIDES = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], dtype=np.uint8)
_DIAGONALS = np.array([[1, 0, 1], [0, 0, 0], [1, 0, 1]], dtype=np.uint8)
# (row step, column step, footprint factor) of the four lines through a pixel
_LINES = ((0, 1, 1.0), (1, 0, 1.0), (1, 1, np.sqrt(2.0)), (1, -1, np.sqrt(2.0)))
#: Share of the image at or below which :func:`flying_points` judges a line's apart pixels' ramp at those pixels
#: (gathered) rather than on the whole image (the two cost the same near 3 %: docs/benchmarks.md, Run 15).
_RAMP_GATHER_SHARE = 0.03
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
    return _beside(z, _neighbour_extremes(z), focal_px, max_step, side)


def _neighbour_extremes(z: np.ndarray) -> list[tuple[np.float32, np.ndarray, np.ndarray]]:
    """``(footprint factor, farthest, nearest)`` of the 4 side and of the 4 diagonal neighbours of every pixel of
    the float32 depth ``z`` (OpenCV's grey-level dilate and erode; NaN neighbours and the outside never count)."""
    finite = np.isfinite(z)
    nearest_fill = np.where(finite, z, np.float32(np.inf))
    farthest_fill = np.where(finite, z, np.float32(-np.inf))
    return [(factor, cv2.dilate(farthest_fill, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=-np.inf),
             cv2.erode(nearest_fill, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=np.inf))
            for kernel, factor in ((_SIDES, np.float32(1.0)), (_DIAGONALS, np.float32(np.sqrt(2.0))))]


def _beside(z: np.ndarray, extremes: list[tuple[np.float32, np.ndarray, np.ndarray]], focal_px: float,
            max_step: float, side: str) -> np.ndarray:
    """:func:`beside_steps` of the float32 depth ``z`` from its :func:`_neighbour_extremes` (one morphology for
    several thresholds)."""
    limit = np.float32(max_step / focal_px) * np.abs(z)  # (H, W), one side step
    out = np.zeros(z.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for factor, farthest, nearest in extremes:
            if side != "far":
                out |= farthest - z > factor * limit
            if side != "near":
                out |= z - nearest > factor * limit
    return out & np.isfinite(z)


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
            rows, cols = np.nonzero(apart)
            on_ramp = on_a_ramp(self.padded, rows + 2, cols + 2, dr, dc, self.max_bend)  # padded: 2 pixels of NaN
            apart[rows[on_ramp], cols[on_ramp]] = False
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

    def at(k: int) -> np.ndarray:  # z_k, NaN outside the image
        r, c = rows + k * dr, cols + k * dc
        inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
        return np.where(inside, z[np.clip(r, 0, height - 1), np.clip(c, 0, width - 1)].astype(np.float64), np.nan)

    line = [at(k) for k in (-2, -1, 0, 1, 2)]
    limit = max_bend * 0.5 * np.abs(line[3] - line[1])
    ramp = np.ones(np.shape(rows), dtype=bool)
    with np.errstate(invalid="ignore"):
        for i in (1, 2, 3):
            ramp &= np.abs(line[i - 1] - 2.0 * line[i] + line[i + 1]) <= limit
    return ramp


def depth_per_pixel(projector_x: np.ndarray, depth_at: Callable[[np.ndarray, np.ndarray], np.ndarray],
                    axis: str = "x", depth: np.ndarray | None = None,
                    where: np.ndarray | None = None) -> np.ndarray:
    """The depth change along each pixel's ray when its projector coordinate moves by one camera pixel's worth of
    fringe, ``|dz/dx_p| * g`` (H, W): what a phase taken one camera pixel off the pixel's centre costs in depth.

    ``g`` is the median of ``|x_p|``'s change between neighbouring camera pixels along the fringe axis (projector
    pixels per camera pixel; one number per image: the fringes' scale barely changes over a scene).

    Parameters
    ----------
    projector_x : ndarray (H, W)
        Projector coordinate of every pixel (NaN where none).
    depth_at : callable
        ``depth_at(x, pixels)``: camera depth ``z`` (M,) of the projector coordinates ``x`` (M,) at the flat pixel
        indices ``pixels`` (M,) (the caller's triangulation, e.g.
        ``Triangulator.camera_points(x, pixels=pixels)[:, 2]``).
    axis : str
        ``"x"`` or ``"y"``: the camera axis the fringes vary along most (the capture's fringe axis).
    depth : ndarray (H, W), optional
        ``depth_at`` of ``projector_x`` at every pixel when the caller has it already.
    where : ndarray (H, W) bool, optional
        The pixels it is computed at (NaN elsewhere): :func:`edge_points` asks for the few beside an unlit pixel,
        so the second triangulation costs those pixels only. None: every pixel.
    """
    x_p = np.asarray(projector_x, dtype=np.float64)
    out = np.full(x_p.shape, np.nan)
    if where is None:
        pixels = np.arange(x_p.size)
    else:
        if np.shape(where) != x_p.shape:
            raise ValueError(f"where must have the projector coordinate's shape {x_p.shape}; got {np.shape(where)}")
        pixels = np.flatnonzero(where)
        if pixels.size == 0:
            return out
    steps = np.abs(np.diff(x_p, axis=1 if axis == "x" else 0))
    steps = steps[np.isfinite(steps)]
    if steps.size == 0:
        return out
    g = float(bracketed_median(steps))
    x = x_p.ravel()[pixels]  # (M,)
    base = (np.asarray(depth_at(x, pixels), dtype=np.float64) if depth is None
            else np.asarray(depth).ravel()[pixels].astype(np.float64))
    out.ravel()[pixels] = np.abs(np.asarray(depth_at(x + g, pixels), dtype=np.float64) - base)
    return out


@dataclass(frozen=True, eq=False)
class EdgePoints:
    """Pixels :func:`edge_points` drops, by reason, each (H, W) bool (a pixel may have several reasons)."""

    flying: np.ndarray
    beside_step: np.ndarray
    modulation_dip: np.ndarray
    isolated: np.ndarray
    shadow_border: np.ndarray

    @property
    def dropped(self) -> np.ndarray:
        """(H, W) bool: dropped for any reason."""
        return self.flying | self.beside_step | self.modulation_dip | self.isolated | self.shadow_border

    def counts(self, points: np.ndarray) -> dict[str, int]:
        """How many of the pixels with a point (``points`` (H, W) bool) each reason drops, and ``"total"``."""
        points = np.asarray(points, dtype=bool)
        return {"flying": int(np.count_nonzero(self.flying & points)),
                "beside_step": int(np.count_nonzero(self.beside_step & points)),
                "modulation_dip": int(np.count_nonzero(self.modulation_dip & points)),
                "shadow_border": int(np.count_nonzero(self.shadow_border & points)),
                "isolated": int(np.count_nonzero(self.isolated & points)),
                "total": int(np.count_nonzero(self.dropped & points))}


def edge_points(depth: np.ndarray, focal_px: float, modulation: np.ndarray | None = None, *,
                lit: np.ndarray | None = None,
                depth_per_px: np.ndarray | Callable[[np.ndarray], np.ndarray] | None = None,
                max_edge_error: float | None = None, axis: str = "x", max_slope: float = DEFAULT_MAX_SLOPE,
                max_step: float = DEFAULT_MAX_STEP, min_modulation_ratio: float = DEFAULT_MIN_MODULATION_RATIO,
                min_neighbours: int = DEFAULT_MIN_NEIGHBOURS,
                max_ramp_bend: float = DEFAULT_MAX_RAMP_BEND) -> EdgePoints:
    """The points at depth edges to drop: flying points, points beside a depth step, modulation dips at edges,
    partly shadowed points, isolated points (module docstring).

    Parameters
    ----------
    depth : ndarray (H, W)
        Depth along the camera axis, NaN where there is no point.
    focal_px : float
        The camera's focal length, pixels.
    modulation : ndarray (H, W), optional
        Fringe modulation ``B`` of every pixel (also where there is no point: a shadowed neighbour counts), any
        unit; NaN allowed. None skips the modulation and shadow tests (their masks are all False).
    lit : ndarray (H, W) bool, optional
        Pixels with a phase (the unwrapping's valid mask, before any confidence threshold): their complement is the
        projector's shadow and what lies off it. None: the pixels with a point.
    depth_per_px : ndarray (H, W) or callable, optional
        :func:`depth_per_pixel`, in the depth's unit: with ``max_edge_error``, a partly shadowed point predicted
        farther off is dropped. A callable is asked once, with the (H, W) bool mask of the pixels it is needed at
        (those beside an unlit pixel and not already in the shadow), and returns it there (NaN elsewhere):
        ``lambda where: depth_per_pixel(x_p, depth_at, axis, depth=depth, where=where)`` triangulates those pixels
        only, with the same marks as the whole image's array.
    max_edge_error : float, optional
        Largest depth error of a point kept at an edge, in the depth's unit (:data:`DEFAULT_MAX_EDGE_ERROR_MM`
        converted). None: no predicted-error test and no point kept for a side continuing to it.
    axis : str
        ``"x"`` or ``"y"``: the camera axis the fringes' phase varies along (the capture's fringe axis); only the
        part of a partly shadowed pixel's offset along it moves its phase.
    max_slope, max_step, min_modulation_ratio, min_neighbours, max_ramp_bend
        See the module docstring; ``max_step`` inf, ``min_modulation_ratio`` 0 and ``min_neighbours`` 0 turn those
        tests off, ``max_ramp_bend`` 0 keeps no steep plane.

    Returns
    -------
    EdgePoints
    """
    if not (np.isfinite(min_modulation_ratio) and 0.0 <= min_modulation_ratio <= 1.0):
        raise ValueError(f"min_modulation_ratio must be in [0, 1]; got {min_modulation_ratio}")
    if not 0 <= int(min_neighbours) <= 8:
        raise ValueError(f"min_neighbours must be 0 to 8 (of the 8 neighbours); got {min_neighbours}")
    if not max_step > 0:
        raise ValueError(f"max_step must be > 0 pixel footprints (inf: off); got {max_step}")
    if max_edge_error is not None and not (np.isfinite(max_edge_error) and max_edge_error > 0):
        raise ValueError(f"max_edge_error must be > 0 (a depth, the depth's unit) or None; got {max_edge_error}")
    if axis not in ("x", "y"):
        raise ValueError(f"axis must be 'x' or 'y' (the camera axis the fringes vary along); got {axis!r}")
    z = np.asarray(depth)
    if z.ndim != 2:
        raise ValueError(f"depth must be an (H, W) image; got shape {z.shape}")
    z32 = z.astype(np.float32, copy=False)  # what the neighbour tests compare (OpenCV's morphology in float32)
    flying = flying_points(z32, focal_px, max_slope=max_slope, max_ramp_bend=max_ramp_bend)
    solid = np.where(flying, np.float32(np.nan), z32)  # a flying point (a lone wrong order too) makes no step
    has_point = np.isfinite(z32)
    unlit = ~(has_point if lit is None else np.asarray(lit, dtype=bool))
    if unlit.shape != z.shape:
        raise ValueError(f"lit must have the depth's shape {z.shape}; got {unlit.shape}")
    beside_unlit = has_point & (_neighbour_count(unlit) > 0)
    dipped = np.zeros(z.shape, dtype=bool)
    shadow = np.zeros(z.shape, dtype=bool)
    if modulation is not None:
        b = np.asarray(modulation, dtype=np.float32)
        if b.shape != z.shape:
            raise ValueError(f"modulation must have the depth's shape {z.shape}; got {b.shape}")
        brightest = _neighbour_max(np.where(np.isfinite(b), b, -np.inf))
        if min_modulation_ratio > 0:
            with np.errstate(invalid="ignore"):
                dipped = has_point & (b < min_modulation_ratio * brightest)
        # the shadow tests judge the pixels beside an unlit one: computed there only, each as on the whole image
        border = np.flatnonzero(beside_unlit)  # (M,) flat indices
        with np.errstate(invalid="ignore", divide="ignore"):
            lit_fraction = np.clip(b.ravel()[border] / brightest.ravel()[border], 0.0, 1.0)  # NaN where B is
        in_shadow = ~(lit_fraction >= MIN_LIT_FRACTION)
        np.put(shadow, border[in_shadow], True)
        if depth_per_px is not None and max_edge_error is not None:
            judged = border[~in_shadow]  # the only pixels the predicted error can add
            if callable(depth_per_px):
                where = np.zeros(z.shape, dtype=bool)
                np.put(where, judged, True)
                per_px = np.asarray(depth_per_px(where), dtype=np.float64)
            else:
                per_px = np.asarray(depth_per_px, dtype=np.float64)
            if per_px.shape != z.shape:
                raise ValueError(f"depth_per_px must have the depth's shape {z.shape}; got {per_px.shape}")
            with np.errstate(invalid="ignore"):
                error = (0.5 * (1.0 - lit_fraction[~in_shadow]) * per_px.ravel()[judged]
                         * _across_fringes(unlit, axis, judged))
            np.put(shadow, judged[error > max_edge_error], True)
    extremes = _neighbour_extremes(solid)  # the nearest and farthest neighbours, for both thresholds below
    step = np.zeros(z.shape, dtype=bool)
    if np.isfinite(max_step):
        step = _beside(solid, extremes, focal_px, max_step, "both") & ~flying  # both sides: the module docstring
    edge = _beside(solid, extremes, focal_px, max_slope, "both")
    dip = dipped & (edge | (_neighbour_count(edge) > 0))  # within one pixel of a depth edge
    # a pure side (no flying point, no dip, not beside a step: a line of mixed pixels along an edge continues
    # itself) that continues to a dipped point vouches for it. Not for a point beside a step (module docstring), nor
    # for a partly shadowed point (the shadow test judges it); asked at the dips it could keep only
    # the same side vouches for a point beside a step whose modulation does not dip (its footprint holds no sliver
    # of the other side that moves its phase; module docstring)
    if max_edge_error is not None:
        pure = has_point & ~flying & ~dipped & ~step
        dip &= ~continues_a_side(z, pure, 0.5 * max_edge_error, where=dip & ~beside_unlit)
        step &= ~continues_a_side(z, pure, 0.5 * max_edge_error, where=step & ~dipped)
    isolated = np.zeros(z.shape, dtype=bool)
    if min_neighbours > 0:
        kept = has_point & ~flying & ~step & ~dip & ~shadow
        isolated = kept & (_neighbour_count(kept) < int(min_neighbours))
    return EdgePoints(flying=flying, beside_step=step, modulation_dip=dip, isolated=isolated, shadow_border=shadow)


def _across_fringes(unlit: np.ndarray, axis: str, pixels: np.ndarray | None = None) -> np.ndarray:
    """``|cos|`` of the angle between the shadow border's normal (the gradient of the unlit mask, 3x3 Sobel) and
    the fringe axis, (H, W) float32, or (M,) at the flat indices ``pixels``: the share of a lit part's offset that
    moves the phase. (The Sobel sums of a 0/1 mask are small integers: exact in int16 as in float32.)"""
    mask = np.asarray(unlit, dtype=np.uint8)
    gx = cv2.Sobel(mask, cv2.CV_16S, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(mask, cv2.CV_16S, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    if pixels is None:
        gx, gy = gx.astype(np.float32), gy.astype(np.float32)
    else:
        gx, gy = gx.ravel()[pixels].astype(np.float32), gy.ravel()[pixels].astype(np.float32)
    along = np.abs(gx if axis == "x" else gy)
    return along / np.maximum(np.hypot(gx, gy), np.float32(1e-6))


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
        index = np.clip(r, 0, height - 1) * width + np.clip(c, 0, width - 1)
        return np.where(inside & flat_pure[index], flat_depth[index].astype(np.float64), np.nan)

    hit = np.zeros(pixels.size, dtype=bool)
    with np.errstate(invalid="ignore"):
        for dr, dc in _DIRECTIONS:
            first, second = pure_depth(rows + dr, cols + dc), pure_depth(rows + 2 * dr, cols + 2 * dc)
            hit |= np.abs(z - (2.0 * first - second)) <= tolerance
    out = np.zeros(depth.shape, dtype=bool)
    np.put(out, pixels[hit], True)
    return out


def _neighbour_max(values: np.ndarray) -> np.ndarray:
    """The largest of each pixel's 8 neighbours (float32; -inf outside the image)."""
    return cv2.dilate(np.asarray(values, dtype=np.float32), _NEIGHBOURS, borderType=cv2.BORDER_CONSTANT,
                      borderValue=-np.inf)


def _neighbour_count(mask: np.ndarray) -> np.ndarray:
    """How many of each pixel's 8 neighbours are set (outside the image: none)."""
    return cv2.filter2D(mask.astype(np.uint8), cv2.CV_16S, _NEIGHBOURS.astype(np.float32),
                        borderType=cv2.BORDER_CONSTANT)
