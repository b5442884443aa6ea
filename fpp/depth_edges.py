"""Flying points at depth edges: mixed pixels found from the geometry and from the fringes' own modulation.

A camera pixel that straddles a depth edge integrates foreground and background; its fringe phase is a blend of
the two (the sum of two phasors), so it triangulates to a point between the surfaces, or anywhere when the two
phases nearly cancel: a "flying point". A surface seen edge-on (its normal almost perpendicular to the camera ray)
gives points whose depth changes by many pixel footprints from one pixel to the next: kept where that change runs
on straight over five pixels (a plane, measured right), dropped where it bends (a corner or a limb).

The tests live in modules of one idea each, combined here by :func:`edge_points`: :mod:`dptpu.fpp.flying_points`
(pixels apart from both neighbours along a line, and the straight-ramp test that keeps a steep plane's),
:mod:`dptpu.fpp.depth_steps` (the last pixel beside a depth step, and the continuation of a pure side that vouches
for a point) and :mod:`dptpu.fpp.shadow_border` (partly shadowed points beside a projector shadow).

Besides the flying points (:func:`~dptpu.fpp.flying_points.flying_points`), four more signs of a pixel that straddles
an edge, all used by :func:`edge_points`:

- a neighbour more than ``max_step`` footprints nearer or farther (:func:`~dptpu.fpp.depth_steps.beside_steps`): the
  last pixel on each side of a depth step (a step, not a slope: 10 footprints between neighbours is a surface 84
  degrees from facing the camera) may integrate a sliver of the other side, whose phase is far from its own. The
  flying points are taken out first: a lone wrong point is flying, and its right neighbours are not beside a step.
  Such a point is kept where its modulation does not dip (below) and a pure side continues to it within
  ``max_edge_error / 2`` (:func:`~dptpu.fpp.depth_steps.continues_a_side`): a sliver of the other side adds a phasor
  of another phase, which lowers the modulation, and moves the phase, which takes the point off its side's line; a
  pixel that shows neither lies on its side's surface within the tolerance (a band one order off beside a step,
  which continued itself on the main job's random-1 when the side's continuation alone kept a point, 0.054 -> 0.186
  % wrong on an older tree, is caught by the islands and the confidence now: the main job's configuration offline,
  MW 64/63, the network without its consensus, random-1 0.036 -> 0.041 % wrong at 91.78 -> 92.59 % complete);
- its fringe modulation ``B`` dips below ``min_modulation_ratio`` times the largest of its 8 neighbours' AND it lies
  at a depth edge (within one pixel of a pixel with a neighbour more than ``max_slope`` footprints away) or beside
  an unlit pixel: the phasors of two surfaces (or of a lit surface and a projector shadow) add to less than either.
  A dip on a smooth surface is an albedo (texture) edge, whose phase is right: kept; so is a dip (not beside an
  unlit pixel) that a pure side continues to within ``max_edge_error / 2``
  (:func:`~dptpu.fpp.depth_steps.continues_a_side`);
- beside an unlit pixel (a projector shadow), a ``shadow_border`` point whose lit fraction ``r = B / B_max`` (of its
  8 neighbours) is below :data:`~dptpu.fpp.shadow_border.MIN_LIT_FRACTION` (its centre lies in the shadow) or whose
  predicted depth error exceeds ``max_edge_error``: a partly shadowed pixel carries the phase of its lit part only,
  whose centre lies ``(1 - r) / 2`` pixels off the pixel's centre, across the shadow's border; the part of that
  offset along the fringe axis (``|cos|`` of the border normal's angle to it) times
  :func:`~dptpu.fpp.shadow_border.depth_per_pixel`, the depth change along the pixel's ray when its projector
  coordinate moves by one camera pixel's worth of fringe, is its depth error (a narrow baseline makes it large: 5
  degrees, ~10 mm per pixel on the twin's f1300 rig; 20 degrees, ~1 mm);
- it has fewer than ``min_neighbours`` of its 8 neighbours left with a point: a sliver between edges or shadows,
  which no neighbour confirms.

An albedo edge at a depth edge or a shadow also dips the modulation; its pixels are dropped though their depth is
right (completeness, never precision, pays for it).

The tests that concern a few pixels are computed at those pixels only, each with the arithmetic it has on the whole
image (the same marks bit for bit): the lit fraction and the predicted error of the pixels beside an unlit one
(``depth_per_px`` as a callable: the second triangulation of :func:`~dptpu.fpp.shadow_border.depth_per_pixel` at
those pixels), the continuation of a side at the dips it could keep. The straight-ramp test and the continuation
beside a step are gathered at their pixels where those are few and run on the whole image where many ask (a steep
plane), with the same marks either way.

Parameters and why (``docs/nodes.md``, "Flying points", has the measurements behind the defaults):

- ``max_slope``, ``max_ramp_bend``: :mod:`dptpu.fpp.flying_points`.
- ``max_step`` (default :data:`~dptpu.fpp.depth_steps.DEFAULT_MAX_STEP` = 10): on the twin's outside-rig scenes the
  last pixel beside a step held half of what stayed off the surface; those its side continues to without a dip are
  kept (above).
- ``min_modulation_ratio`` (default :data:`DEFAULT_MIN_MODULATION_RATIO` = 0.6): a pixel at 60 % of its brightest
  neighbour's modulation; noise and smooth shading change ``B`` by a few percent between neighbours, texture by more
  (0.7 halves what stays off the surface again but costs about 0.7 % of completeness on textured scenes; at 0.8 the
  noise of 3-step captures starts to trigger it).
- ``max_edge_error`` (depth units; ``dptpu triangulate``, the cloud node and ``dptpu eval cloud`` pass
  :data:`DEFAULT_MAX_EDGE_ERROR_MM` = 1 mm in the rig's unit, the off-surface bound of ``dptpu eval cloud``; None
  turns the predicted-error test and the continuation off).
- ``min_neighbours`` (default :data:`DEFAULT_MIN_NEIGHBOURS` = 2)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._neighbours import neighbour_count, neighbour_max
from .depth_steps import DEFAULT_MAX_STEP, continues_a_side, neighbour_steps, steps_beside
from .flying_points import DEFAULT_MAX_RAMP_BEND, DEFAULT_MAX_SLOPE, flying_points
from .shadow_border import shadow_border

__all__ = ["DEFAULT_MAX_EDGE_ERROR_MM", "DEFAULT_MIN_MODULATION_RATIO", "DEFAULT_MIN_NEIGHBOURS", "EdgePoints",
           "edge_points"]

#: A pixel whose modulation is below this fraction of its brightest 8-neighbour's is a mixed pixel.
DEFAULT_MIN_MODULATION_RATIO = 0.6
#: A point with fewer of its 8 neighbours holding a point is a sliver.
DEFAULT_MIN_NEIGHBOURS = 2
#: Largest depth error of a point kept at an edge (predicted for a partly shadowed one; a modulation dip is kept
#: where a pure side continues to it within half of it), millimetres: convert to the depth's unit.
DEFAULT_MAX_EDGE_ERROR_MM = 1.0


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
        :func:`~dptpu.fpp.shadow_border.depth_per_pixel`, in the depth's unit: with ``max_edge_error``, a partly
        shadowed point predicted farther off is dropped. A callable is asked once, with the (H, W) bool mask of the
        pixels it is needed at (those beside an unlit pixel and not already in the shadow), and returns it there (NaN
        elsewhere):
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
    beside_unlit = has_point & (neighbour_count(unlit) > 0)
    dipped = np.zeros(z.shape, dtype=bool)
    shadow = np.zeros(z.shape, dtype=bool)
    if modulation is not None:
        b = np.asarray(modulation, dtype=np.float32)
        if b.shape != z.shape:
            raise ValueError(f"modulation must have the depth's shape {z.shape}; got {b.shape}")
        brightest = neighbour_max(np.where(np.isfinite(b), b, -np.inf))
        if min_modulation_ratio > 0:
            with np.errstate(invalid="ignore"):
                dipped = has_point & (b < min_modulation_ratio * brightest)
        # the shadow tests judge the pixels beside an unlit one: computed there only, each as on the whole image
        shadow = shadow_border(b, brightest, beside_unlit, unlit, depth_per_px=depth_per_px,
                               max_edge_error=max_edge_error, axis=axis)
    steps = neighbour_steps(solid)  # how far the farthest and the nearest neighbours lie, for both thresholds below
    step = np.zeros(z.shape, dtype=bool)
    if np.isfinite(max_step):
        step = steps_beside(solid, steps, focal_px, max_step, "both") & ~flying  # both sides: the module docstring
    edge = steps_beside(solid, steps, focal_px, max_slope, "both")
    dip = dipped & (edge | (neighbour_count(edge) > 0))  # within one pixel of a depth edge
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
        isolated = kept & (neighbour_count(kept) < int(min_neighbours))
    return EdgePoints(flying=flying, beside_step=step, modulation_dip=dip, isolated=isolated, shadow_border=shadow)
