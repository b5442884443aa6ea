"""Phase -> projector coordinate -> 3D points, with the lens distortion of camera and projector.

A camera pixel defines a ray ``X(t) = C + t w`` (``C`` the camera centre, ``w`` its undistorted direction in
world coordinates). The measured projector coordinate ``c`` along the fringe axis gives one plane through the
projector centre, ``(a - c b) . [X, 1] = 0``, with ``a`` the projector projection matrix row of that axis and
``b`` its third row (the paper's Eq. (10) for the projector as an inverse camera). Substituting the ray:

    t = (c beta - alpha) / (gamma - c delta),   alpha = a.[C,1], beta = b.[C,1], gamma = a[:3].w, delta = b[:3].w

``gamma`` and ``delta`` are per-pixel constants, so :class:`Triangulator` precomputes them once per rig and a
scan costs a few vector operations. The projector measures only one coordinate of its distorted image; along a
pixel's ray that measured coordinate is a polynomial of the ideal one (:mod:`._ray_distortion`, precomputed per
pixel), which Newton's method inverts in two or three passes over (H, W) arrays. It converges to the fixed point
of the textbook iteration (triangulate, project the point into the projector, move the ideal coordinate by the
difference between the measured and the re-distorted coordinate, repeat), which
:func:`triangulate_reference` still runs.

:func:`triangulate_reference` keeps the textbook per-pixel 3x3 linear solve as the reference for tests and
benchmarks.
"""
from __future__ import annotations

import numpy as np

from ._ray_distortion import RayDistortion
from .calibration import DeviceModel, Rig
from .distortion import distort, normalized_to_pixels, pixels_to_normalized, undistort

_AXES = {"x": 0, "y": 1}


def projector_coordinate(absolute_phase: np.ndarray, frequency: float, extent: float) -> np.ndarray:
    """Projector coordinate along the fringe axis from absolute phase, ``x_p = phi W / (2 pi f)``.

    Inverse of the convention ``phi = 2 pi f x_p / W`` (docs/architecture.md). NaN stays NaN.
    """
    if not np.isfinite(frequency) or frequency <= 0:
        raise ValueError(f"frequency must be a positive number of periods; got {frequency}")
    if not np.isfinite(extent) or extent <= 0:
        raise ValueError(f"projector extent must be positive pixels; got {extent}")
    return np.multiply(absolute_phase, extent / (2.0 * np.pi * frequency), dtype=np.float64)  # one pass


def _axis_index(axis: str) -> int:
    if axis not in _AXES:
        raise ValueError(f"fringe axis must be 'x' or 'y'; got {axis!r}")
    return _AXES[axis]


def camera_rays(camera: DeviceModel, *, distortion: bool = True) -> np.ndarray:
    """Unit ray directions in world coordinates of every camera pixel, (H, W, 3).

    Convention: pixel (u, v) = (column, row), 0-based centres.
    """
    width, height = camera.size
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    xy = pixels_to_normalized(np.stack([u, v], axis=-1), camera.K)  # (H, W, 2), distorted
    if distortion:
        xy = undistort(xy, camera.dist)
    rays_cam = np.concatenate([xy, np.ones((height, width, 1))], axis=-1)  # (H, W, 3)
    rays_world = rays_cam @ camera.R  # R^T applied to each row vector
    return rays_world / np.linalg.norm(rays_world, axis=-1, keepdims=True)


class Triangulator:
    """Precomputed triangulation of whole images for one rig and fringe axis.

    Parameters
    ----------
    rig : Rig
    axis : {"x", "y"}
        Projector axis along which the phase varies ("x": vertical stripes, the column is measured).
    distortion : bool
        Correct camera and projector lens distortion (default). False gives the pinhole result of the paper's
        reconstruction script.
    projector_iterations : int
        Most Newton passes for the projector distortion (each pass stops early once converged, see
        :data:`dptpu.fpp._ray_distortion.STEP_TOLERANCE_PX`); 0 ignores the projector's distortion.

    Notes
    -----
    The construction (camera rays, and with projector distortion the per-pixel polynomials of
    :mod:`._ray_distortion`) is the expensive part, done once per rig and axis; :meth:`points` and
    :meth:`camera_points` then cost a few dozen passes over (H, W) arrays (timings and memory:
    docs/benchmarks.md, ``dptpu bench fpp``, node paths).
    """

    def __init__(self, rig: Rig, *, axis: str = "x", distortion: bool = True, projector_iterations: int = 6):
        self.rig = rig
        self.axis = _axis_index(axis)
        self.distortion = distortion
        self.projector_iterations = projector_iterations if distortion else 0
        self.origin = rig.camera.center  # (3,)
        self.rays = camera_rays(rig.camera, distortion=distortion)  # (H, W, 3)
        self._rays_camera_cast: dict[tuple, np.ndarray] = {}  # (dtype, scale) -> scaled planar camera rays
        P = rig.projector.projection_matrix  # (3, 4)
        a, b = P[self.axis], P[2]
        origin_h = np.append(self.origin, 1.0)
        self._alpha = float(a @ origin_h)
        self._beta = float(b @ origin_h)
        self._gamma = self.rays @ a[:3]  # (H, W)
        self._delta = self.rays @ b[:3]  # (H, W)
        self._rays_planar = np.ascontiguousarray(np.moveaxis(self.rays, -1, 0))  # (3, H, W)
        self._projector_distortion = None
        if self.projector_iterations > 0 and np.any(np.asarray(rig.projector.dist) != 0):
            distortion_model = RayDistortion(rig.projector, self.origin, self.rays, self.axis)
            self._projector_distortion = distortion_model
            # t in terms of u = (c - mid) / half: (u beta_u - alpha_u) / (gamma_u - u delta_u).
            mid, half = distortion_model.mid_px, distortion_model.half_px
            self._alpha_u = self._alpha - mid * self._beta
            self._beta_u = half * self._beta
            self._gamma_u = self._gamma - mid * self._delta  # (H, W)
            self._delta_u = half * self._delta  # (H, W)

    @property
    def shape(self) -> tuple[int, int]:
        return self._gamma.shape

    def _points_on_plane(self, coord: np.ndarray) -> np.ndarray:
        """Points (H, W, 3) where each pixel's ray meets the projector plane of ideal coordinate ``coord``."""
        return self.origin + self.ray_parameter(coord, ideal=True)[..., None] * self.rays

    def ray_parameter(self, projector_coord: np.ndarray, *, ideal: bool = False,
                      pixels: np.ndarray | None = None) -> np.ndarray:
        """Distance ``t`` (H, W) along each unit ray from the camera centre to its point, rig units.

        ``X = C + t w`` in world coordinates, and ``X_cam = t w_cam`` in the camera frame, so ``t`` is also the
        range from the camera. ``projector_coord`` (H, W) is measured (distorted) unless ``ideal``. NaN where
        the coordinate is NaN; ``t <= 0`` for a point behind the camera. With ``pixels`` (M,) flat pixel indices,
        ``projector_coord`` and the result are (M,): those pixels only, each computed as in a whole image
        (:meth:`camera_points`).
        """
        coord = np.asarray(projector_coord, dtype=np.float64)
        alpha, beta, gamma, delta = self._alpha, self._beta, self._gamma, self._delta
        distortion = None if ideal else self._projector_distortion
        if distortion is not None:
            alpha, beta, gamma, delta = self._alpha_u, self._beta_u, self._gamma_u, self._delta_u
        if pixels is None:
            if coord.shape != self.shape:
                raise ValueError(f"projector_coord must have the camera's shape {self.shape}; got {coord.shape}")
        else:
            pixels = self._pixel_indices(pixels, coord)
            gamma, delta = np.take(gamma, pixels), np.take(delta, pixels)
        if distortion is not None:
            coord = distortion.ideal_u(coord, max_iterations=self.projector_iterations, pixels=pixels)
        with np.errstate(divide="ignore", invalid="ignore"):
            numerator = coord * beta
            numerator -= alpha
            denominator = coord * delta
            np.subtract(gamma, denominator, out=denominator)
            numerator /= denominator
        return numerator  # (H, W): t = (c beta - alpha) / (gamma - c delta)

    def _pixel_indices(self, pixels: np.ndarray, coord: np.ndarray) -> np.ndarray:
        """``pixels`` as (M,) flat indices into the camera image, checked against ``coord`` (M,)."""
        index = np.asarray(pixels)
        if index.ndim != 1 or not np.issubdtype(index.dtype, np.integer) or coord.shape != index.shape:
            raise ValueError(f"pixels must be (M,) flat pixel indices and projector_coord (M,) beside them; got "
                             f"{index.shape} {index.dtype} and {coord.shape}")
        size = self.shape[0] * self.shape[1]
        if index.size and not (0 <= int(index.min()) and int(index.max()) < size):
            raise ValueError(f"pixels must be flat indices in [0, {size}); got {index.min()}..{index.max()}")
        return index.astype(np.intp, copy=False)

    def points(self, projector_coord: np.ndarray, *, pixels: np.ndarray | None = None) -> np.ndarray:
        """3D points in world coordinates (rig units), (H, W, 3) float64; NaN where the coordinate is NaN.

        Parameters
        ----------
        projector_coord : ndarray (H, W)
            Measured (distorted) projector coordinate along the fringe axis, pixels, NaN where invalid.
        pixels : ndarray (M,) int, optional
            Flat indices of the pixels to triangulate: ``projector_coord`` is then (M,) and the result (M, 3), each
            pixel's point as in a whole image (see :meth:`camera_points`).
        """
        t = self.ray_parameter(projector_coord, pixels=pixels)  # (H, W) or (M,)
        rays = self._rays_planar
        if pixels is not None:
            rays = np.take(rays.reshape(3, -1), np.asarray(pixels, dtype=np.intp), axis=1)  # (3, M)
        points = np.empty((*t.shape, 3))  # (H, W, 3) or (M, 3)
        for k in range(3):  # per coordinate: a broadcast over the last axis of 3 is several times slower
            np.multiply(t, rays[k], out=points[..., k])
            points[..., k] += self.origin[k]
        return points

    def camera_points(self, projector_coord: np.ndarray, *, scale: float = 1.0, dtype=np.float32,
                      out: np.ndarray | None = None, pixels: np.ndarray | None = None) -> np.ndarray:
        """3D points in the camera frame, ``(R X + T) * scale``, (H, W, 3) of ``dtype``; the cloud's output.

        Parameters
        ----------
        projector_coord : ndarray (H, W)
            Measured (distorted) projector coordinate along the fringe axis, pixels, NaN where invalid.
        scale : float
            Factor from rig units to the output's, e.g. ``rig.scale_to_m`` for metres.
        dtype : numpy dtype
            Output dtype (float32 by default, as PointCloud2 and depth images carry).
        out : ndarray (H, W, 3) of ``dtype``, optional
            Where to write the points; may be a strided view, e.g. the x, y, z channels of an (H, W, C) point
            cloud buffer, so the cloud is filled without a copy.
        pixels : ndarray (M,) int, optional
            Flat indices of the pixels to triangulate: ``projector_coord`` is then (M,), their coordinates, and the
            result (M, 3) (``out`` not allowed). Each pixel goes through the same operations as in a whole image:
            the same points bit for bit whenever the projector distortion's Newton passes stop after as many
            passes (:meth:`dptpu.fpp._ray_distortion.RayDistortion.ideal_u`), and always without it. For a
            caller that needs a few pixels of a second triangulation (``fpp.shadow_border.depth_per_pixel``).

        Returns
        -------
        ndarray (H, W, 3)
            ``X_cam = t w_cam * scale`` (the camera centre is the origin of its frame); NaN where the coordinate
            is NaN or the point is not in front of the camera (``z <= 0``). Equals
            ``(points(c) @ R.T + T) * scale`` up to rounding, in one pass over the output.
        """
        if pixels is not None and out is not None:
            raise ValueError("out is for whole images; camera_points with pixels returns a new (M, 3) array")
        t = self.ray_parameter(projector_coord, pixels=pixels).astype(dtype)  # (H, W) rig units; NaN stays NaN
        np.copyto(t, np.nan, where=t <= 0)  # behind the camera
        key = (np.dtype(dtype), float(scale))
        if key not in self._rays_camera_cast:  # (3, H, W) planar unit rays times scale, in the output dtype
            self._rays_camera_cast.clear()
            rays_camera = self._rays_planar.reshape(3, -1).T @ (self.rig.camera.R.T * scale)  # (H*W, 3): R w
            self._rays_camera_cast[key] = np.ascontiguousarray(rays_camera.T.reshape(self._rays_planar.shape),
                                                               dtype=dtype)
        rays = self._rays_camera_cast[key]
        if pixels is not None:
            rays = np.take(rays.reshape(3, -1), np.asarray(pixels, dtype=np.intp), axis=1)  # (3, M)
            points = np.empty((t.size, 3), dtype=dtype)
        elif out is None:
            points = np.empty(self.rays.shape, dtype=dtype)  # (H, W, 3)
        elif out.shape != self.rays.shape or out.dtype != np.dtype(dtype):
            raise ValueError(f"out must be an array of shape {self.rays.shape} and dtype {np.dtype(dtype)}; got "
                             f"{out.shape} {out.dtype}")
        else:
            points = out
        for k in range(3):
            np.multiply(t, rays[k], out=points[..., k])
        return points

    def depth(self, points: np.ndarray) -> np.ndarray:
        """Z of ``points`` (H, W, 3) in the camera frame, rig units, (H, W)."""
        return points @ self.rig.camera.R[2] + self.rig.camera.T[2]


def camera_depth(points: np.ndarray, camera: DeviceModel) -> np.ndarray:
    """Camera ``z`` (...) of world points (..., 3): ``(points @ R.T + T)[..., 2]``, the same values bit for bit for
    a whole image and for any rows of it (numpy's matmul takes BLAS's matrix-vector path for a single row, whose
    rounding may differ from the matrix product's: one row is evaluated as two)."""
    rotation, translation = np.asarray(camera.R), np.asarray(camera.T)
    if points.ndim == 2 and points.shape[0] == 1:
        return (np.concatenate([points, points]) @ rotation.T + translation)[:1, 2]
    return (points @ rotation.T + translation)[..., 2]


def triangulate_reference(rig: Rig, pixels: np.ndarray, projector_coord: np.ndarray, *, axis: str = "x",
                          distortion: bool = True, projector_iterations: int = 6) -> np.ndarray:
    """Reference triangulation by one 3x3 linear solve per pixel (the paper's reconstruction), (M, 3).

    Parameters
    ----------
    pixels : ndarray (M, 2)
        Camera pixel coordinates (u, v), distorted (as measured).
    projector_coord : ndarray (M,)
        Measured projector coordinate along ``axis``.

    Rows of each system: ``P_c[0] - u' P_c[2]``, ``P_c[1] - v' P_c[2]``, ``P_p[i] - c' P_p[2]`` with ideal
    (undistorted) ``u', v', c'``. Slow by design: the reference for :class:`Triangulator`.
    """
    index = _axis_index(axis)
    pixels = np.asarray(pixels, dtype=np.float64)
    coord = np.asarray(projector_coord, dtype=np.float64)
    camera, projector = rig.camera, rig.projector
    if distortion:
        xy = undistort(pixels_to_normalized(pixels, camera.K), camera.dist)
        pixels = normalized_to_pixels(xy, camera.K)
    Pc, Pp = camera.projection_matrix, projector.projection_matrix
    ideal = coord.copy()
    points = np.empty((len(coord), 3))
    for _ in range(1 + (projector_iterations if distortion else 0)):
        for i in range(len(coord)):  # per pixel on purpose: this is the reference
            rows = np.array([Pc[0] - pixels[i, 0] * Pc[2], Pc[1] - pixels[i, 1] * Pc[2],
                             Pp[index] - ideal[i] * Pp[2]])
            points[i] = np.linalg.solve(rows[:, :3], -rows[:, 3])
        if distortion:
            X_prj = points @ projector.R.T + projector.T
            xy = X_prj[:, :2] / X_prj[:, 2:3]
            ideal = ideal + (coord - normalized_to_pixels(distort(xy, projector.dist), projector.K)[:, index])
    return points
