"""Surface normals of an organized point cloud from its pixel neighbours, oriented toward the camera.

An organized cloud keeps the camera's pixel grid, so each point's neighbours on the surface are its neighbours in
the image. The tangents along the row and the column are the central differences of the neighbouring points,

    t_u = P(v, u + 1) - P(v, u - 1),    t_v = P(v + 1, u) - P(v - 1, u),

(NaN where a neighbour is missing: NaN or outside the image), summed over a ``window_px`` x ``window_px`` window
of pixels around the point (the finite ones only, so a point beside a hole or on a silhouette takes its tangents
from the neighbours that have them; a symmetric window keeps the estimate's curvature bias of second order and
divides the noise by about the window's width), and the normal is their cross product, normalized:

    n = (sum t_u x sum t_v) / |sum t_u x sum t_v|.

A point with no finite tangent along either axis in its window has no normal (NaN). The normal then points toward
the camera: with the camera at the origin of the cloud's frame (the optical frame), ``n . P <= 0``.

Noise: a depth noise ``sigma`` on points ``s`` apart laterally tilts one central-difference normal by about
``sigma / (sqrt(2) s)`` rad per axis; the window's sum of ``k x k`` of them by about ``1 / k`` of that (neighbouring
central differences share points, so a little more). Depth edges are the cloud's business: :mod:`dptpu.fpp.
depth_edges` drops the points across them first, so no difference spans two surfaces, though a window beside an
edge may sum tangents of both.
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = ["DEFAULT_NORMAL_WINDOW_PX", "organized_normals"]

#: Width in pixels of the window whose tangents are summed (odd); 1 = the point's own central differences.
DEFAULT_NORMAL_WINDOW_PX = 3


def organized_normals(points: np.ndarray, *, window_px: int = DEFAULT_NORMAL_WINDOW_PX,
                      out: np.ndarray | None = None) -> np.ndarray:
    """Unit normals (H, W, 3) float32 of an organized cloud, from the central differences of its pixel neighbours.

    Parameters
    ----------
    points : ndarray (H, W, 3) float32 or float64
        Points in the camera's frame (the camera at the origin; any unit), NaN where a pixel has none. A planar
        view (``planes.transpose(1, 2, 0)`` of (3, H, W) planes) is worked on plane by plane without a copy.
    window_px : int
        Width of the square window whose tangents are summed (odd, >= 1).
    out : ndarray (H, W, 3) float32, optional
        Where to write the normals (e.g. a planar view into a cloud being built).

    Returns
    -------
    ndarray (H, W, 3) float32
        Unit normals, ``n . P <= 0`` (toward the camera); NaN where the point is NaN, where its window has no
        finite tangent along a row or along a column, or where the two summed tangents are parallel. ``out`` when
        given.

    Notes
    -----
    ``n = (sum t_u x sum t_v) / |sum t_u x sum t_v|`` over the window, ``t_u``, ``t_v`` the central differences
    along the row and the column (NaN where a neighbour is missing); see the module docstring.

    Convention: pixel ``(v, u)`` is row ``v``, column ``u``; the result is oriented toward the origin.
    """
    points = np.asarray(points)
    if points.ndim != 3 or points.shape[2] != 3:
        raise ValueError(f"points must have shape (H, W, 3); got {points.shape}")
    if isinstance(window_px, bool) or not isinstance(window_px, (int, np.integer)) or window_px < 1 \
            or window_px % 2 == 0:
        raise ValueError(f"window_px must be an odd integer >= 1; got {window_px!r}")
    if out is None:
        out = np.empty((3, *points.shape[:2]), dtype=np.float32).transpose(1, 2, 0)
    elif out.shape != points.shape or out.dtype != np.float32:
        raise ValueError(f"out must be a float32 array of shape {points.shape}; got {out.dtype} {out.shape}")
    p = [points[..., c].astype(np.float32, copy=False) for c in range(3)]  # x, y, z planes (H, W)
    tu = _window_sum(_tangent(p, axis=1), int(window_px))  # along the row: 3 planes
    tv = _window_sum(_tangent(p, axis=0), int(window_px))  # along the column
    n = []  # t_u x t_v, component by component, in place
    for a, b in ((1, 2), (2, 0), (0, 1)):
        component = np.multiply(tu[a], tv[b])
        component -= tu[b] * tv[a]
        n.append(component)
    length = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])  # (H, W)
    facing = n[0] * p[0] + n[1] * p[1] + n[2] * p[2]  # n . P, NaN where the point is
    with np.errstate(invalid="ignore", divide="ignore"):
        np.divide(np.where(facing > 0, np.float32(-1.0), np.float32(1.0)), length, out=length)  # toward the camera
    length[np.isnan(facing)] = np.nan  # (a zero length, parallel tangents, is inf -> NaN below)
    for c in range(3):
        np.multiply(n[c], length, out=out[..., c])
    out[~np.isfinite(length)] = np.nan
    return out


def _window_sum(tangents: list[np.ndarray], window: int) -> list[np.ndarray]:
    """Sum of each finite tangent plane over a ``window`` x ``window`` box (NaN counts as 0); NaN where the box
    holds no finite tangent."""
    if window == 1:
        return tangents
    finite = ~np.isnan(tangents[2])  # the three components are finite together
    count = cv2.boxFilter(finite.astype(np.float32), -1, (window, window), normalize=False,
                          borderType=cv2.BORDER_CONSTANT)
    summed = []
    for t in tangents:
        total = cv2.boxFilter(np.where(finite, t, np.float32(0.0)), -1, (window, window), normalize=False,
                              borderType=cv2.BORDER_CONSTANT)
        total[count < 0.5] = np.nan
        summed.append(total)
    return summed


def _tangent(points: list[np.ndarray], *, axis: int) -> list[np.ndarray]:
    """Central difference ``P(i + 1) - P(i - 1)`` along ``axis`` (0 rows, 1 columns) of the three (H, W) planes; NaN
    where a neighbour is NaN or outside the image."""
    tangents = []
    for plane in points:
        t = np.full_like(plane, np.nan)
        if axis == 0:
            np.subtract(plane[2:], plane[:-2], out=t[1:-1])
        else:
            np.subtract(plane[:, 2:], plane[:, :-2], out=t[:, 1:-1])
        tangents.append(t)
    return tangents
