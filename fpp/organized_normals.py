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
        Points in the camera's frame (the camera at the origin; any unit), NaN (all three coordinates, as the
        triangulation writes them) where a pixel has none. A planar view (``planes.transpose(1, 2, 0)`` of
        (3, H, W) planes) is worked on plane by plane without a copy.
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

    Kernel: a missing tangent enters the box sums as 0, so a window without any gives a zero sum, a zero cross
    product and no normal, as the definition says, without a count of the finite ones; each step is one float32
    operation over whole planes, in place where it can be, in the same order as the definition's, so the result is
    that of the plain formulation bit for bit (tests/fpp/test_organized_normals.py holds it there).
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
    tu = _window_sums(_tangents(p, axis=1), int(window_px))  # (3, H, W): sum t_u's x, y, z
    tv = _window_sums(_tangents(p, axis=0), int(window_px))  # along the column
    # t_u x t_v: component c is t_u[c + 1] t_v[c + 2] - t_u[c + 2] t_v[c + 1] (indices mod 3)
    n = np.empty_like(tu)  # (3, H, W)
    scratch = np.empty_like(tu)
    for c in range(3):
        np.multiply(tu[(c + 1) % 3], tv[(c + 2) % 3], out=n[c])
        np.multiply(tu[(c + 2) % 3], tv[(c + 1) % 3], out=scratch[c])
    np.subtract(n, scratch, out=n)
    length, term = np.multiply(n[0], n[0]), scratch[0]  # |n|^2 = (n_x^2 + n_y^2) + n_z^2, in this order
    length += np.multiply(n[1], n[1], out=term)
    length += np.multiply(n[2], n[2], out=term)
    np.sqrt(length, out=length)
    facing = np.multiply(n[0], p[0], out=scratch[1])  # n . P = (n_x x + n_y y) + n_z z; NaN where the point is
    facing += np.multiply(n[1], p[1], out=term)
    facing += np.multiply(n[2], p[2], out=term)
    scale = length  # 1 / |n|, negated where n . P > 0 (toward the camera)
    with np.errstate(invalid="ignore", divide="ignore"):
        np.divide(np.float32(1.0), length, out=scale)
        np.negative(scale, out=scale, where=facing > 0)
    # no normal: the point is NaN (so is n . P), or |n| = 0 (no tangent along an axis, or parallel ones): 1/0 = inf
    missing = np.isnan(facing)
    missing |= np.isinf(scale)
    np.copyto(scale, np.float32(np.nan), where=missing)
    for c in range(3):
        np.multiply(n[c], scale, out=out[..., c])
    return out


def _window_sums(tangents: np.ndarray, window: int) -> np.ndarray:
    """Sums of the (3, H, W) tangent planes over a ``window`` x ``window`` box of pixels (zero outside the image),
    in place: the box filter of each plane."""
    if window > 1:
        for plane in tangents:
            cv2.boxFilter(plane, -1, (window, window), dst=plane, normalize=False, borderType=cv2.BORDER_CONSTANT)
    return tangents


def _tangents(points: list[np.ndarray], *, axis: int) -> np.ndarray:
    """Central differences ``P(i + 1) - P(i - 1)`` along ``axis`` (0 rows, 1 columns) of the three (H, W) planes
    as planes x, y, z of a (3, H, W) float32 array; 0 where a neighbour is NaN or outside the image (a missing
    tangent adds nothing to a window's sum)."""
    height, width = points[0].shape
    tangents = np.empty((3, height, width), dtype=np.float32)
    for plane, t in zip(points, tangents):
        if axis == 0:
            np.subtract(plane[2:], plane[:-2], out=t[1:-1])
            t[0] = t[-1] = 0.0
        else:  # OpenCV's subtraction walks the row-strided views 3-4x faster than numpy's; the same float32 values
            cv2.subtract(plane[:, 2:], plane[:, :-2], dst=t[:, 1:-1])
            t[:, 0] = t[:, -1] = 0.0
    cv2.patchNaNs(tangents.reshape(3 * height, width), 0.0)  # NaN differences (a neighbour missing) -> 0
    return tangents
