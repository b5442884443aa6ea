"""Partly shadowed points beside a projector shadow (one of the depth-edge tests combined by
:func:`dptpu.fpp.depth_edges.edge_points`).

Beside an unlit pixel (a projector shadow), a ``shadow_border`` point whose lit fraction ``r = B / B_max`` (of its 8
neighbours) is below :data:`MIN_LIT_FRACTION` (its centre lies in the shadow) or whose predicted depth error exceeds
``max_edge_error``: a partly shadowed pixel carries the phase of its lit part only, whose centre lies ``(1 - r) /
2`` pixels off the pixel's centre, across the shadow's border; the part of that offset along the fringe axis
(``|cos|`` of the border normal's angle to it) times :func:`depth_per_pixel`, the depth change along the pixel's ray
when its projector coordinate moves by one camera pixel's worth of fringe, is its depth error (a narrow baseline
makes it large: 5 degrees, ~10 mm per pixel on the twin's f1300 rig; 20 degrees, ~1 mm).

:func:`shadow_border` judges the pixels beside an unlit one only, each with the arithmetic it has on the whole image
(the same marks bit for bit): the lit fraction, and the predicted error (``depth_per_px`` as a callable: the second
triangulation of :func:`depth_per_pixel` at those pixels).
"""
from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from .bracketed_median import bracketed_median

__all__ = ["MIN_LIT_FRACTION", "depth_per_pixel", "shadow_border"]

#: A point beside an unlit pixel whose modulation is below this fraction of its brightest neighbour's has its centre
#: in the shadow: no surface there is lit (``dptpu eval cloud`` counts such a point as having no true surface).
MIN_LIT_FRACTION = 0.5


def shadow_border(modulation: np.ndarray, brightest: np.ndarray, beside_unlit: np.ndarray, unlit: np.ndarray, *,
                  depth_per_px: np.ndarray | Callable[[np.ndarray], np.ndarray] | None, max_edge_error: float | None,
                  axis: str) -> np.ndarray:
    """The partly shadowed points to drop (module docstring), (H, W) bool.

    Parameters
    ----------
    modulation : ndarray (H, W) float32
        Fringe modulation ``B`` of every pixel, NaN allowed.
    brightest : ndarray (H, W) float32
        The largest ``B`` of each pixel's 8 neighbours.
    beside_unlit : ndarray (H, W) bool
        The points with an unlit neighbour: the only pixels judged.
    unlit : ndarray (H, W) bool
        The pixels without a phase (the projector's shadow and what lies off it).
    depth_per_px, max_edge_error, axis
        As :func:`dptpu.fpp.depth_edges.edge_points`: without both of the first two only the lit fraction is tested.
    """
    shadow = np.zeros(unlit.shape, dtype=bool)
    border = np.flatnonzero(beside_unlit)  # (M,) flat indices
    with np.errstate(invalid="ignore", divide="ignore"):
        lit_fraction = np.clip(modulation.ravel()[border] / brightest.ravel()[border], 0.0, 1.0)  # NaN where B is
    in_shadow = ~(lit_fraction >= MIN_LIT_FRACTION)
    np.put(shadow, border[in_shadow], True)
    if depth_per_px is not None and max_edge_error is not None:
        judged = border[~in_shadow]  # the only pixels the predicted error can add
        if callable(depth_per_px):
            where = np.zeros(unlit.shape, dtype=bool)
            np.put(where, judged, True)
            per_px = np.asarray(depth_per_px(where), dtype=np.float64)
        else:
            per_px = np.asarray(depth_per_px, dtype=np.float64)
        if per_px.shape != unlit.shape:
            raise ValueError(f"depth_per_px must have the depth's shape {unlit.shape}; got {per_px.shape}")
        with np.errstate(invalid="ignore"):
            error = (0.5 * (1.0 - lit_fraction[~in_shadow]) * per_px.ravel()[judged]
                     * _across_fringes(unlit, axis, judged))
        np.put(shadow, judged[error > max_edge_error], True)
    return shadow


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


def _across_fringes(unlit: np.ndarray, axis: str, pixels: np.ndarray | None = None) -> np.ndarray:
    """``|cos|`` of the angle between the shadow border's normal (the gradient of the unlit mask, 3x3 Sobel with
    the border replicated) and the fringe axis, (H, W) float32, or (M,) at the flat indices ``pixels``: the share of
    a lit part's offset that moves the phase. At ``pixels`` the Sobel sums are taken from those pixels' 3x3
    neighbourhoods only (OpenCV's over the whole image cost ~10 times more for the few pixels asked); the sums of a
    0/1 mask are small integers, exact either way, so the result is the same bit for bit."""
    mask = np.asarray(unlit, dtype=np.uint8)
    if pixels is None:
        gx = cv2.Sobel(mask, cv2.CV_16S, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE).astype(np.float32)
        gy = cv2.Sobel(mask, cv2.CV_16S, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE).astype(np.float32)
    else:
        gx, gy = _sobel_at(mask, np.asarray(pixels, dtype=np.intp))
    along = np.abs(gx if axis == "x" else gy)
    return along / np.maximum(np.hypot(gx, gy), np.float32(1e-6))


def _sobel_at(mask: np.ndarray, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 3x3 Sobel derivatives along x and y of the (H, W) uint8 ``mask`` at the flat indices ``pixels`` (M,),
    float32, the image's border replicated (as ``cv2.Sobel(..., BORDER_REPLICATE)``)."""
    height, width = mask.shape
    flat = mask.ravel().astype(np.int16)
    rows, cols = np.divmod(pixels, width)
    above, below = np.maximum(rows - 1, 0) * width, np.minimum(rows + 1, height - 1) * width
    left, right = np.maximum(cols - 1, 0), np.minimum(cols + 1, width - 1)
    row = rows * width
    # kernels [[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]] (x) and its transpose (y)
    gx = (flat[above + right] + 2 * flat[row + right] + flat[below + right]
          - flat[above + left] - 2 * flat[row + left] - flat[below + left])
    gy = (flat[below + left] + 2 * flat[below + cols] + flat[below + right]
          - flat[above + left] - 2 * flat[above + cols] - flat[above + right])
    return gx.astype(np.float32), gy.astype(np.float32)
