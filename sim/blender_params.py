"""The paper's Table 1: a calibrated device (camera, or projector as an inverse camera) as Blender parameters.

A device of the rig model (:class:`dptpu.fpp.calibration.DeviceModel`: ``K`` with skew, Brown-Conrady ``dist``,
world -> device ``R``, ``T``, ``size``) becomes a Blender object placed by

- location ``P = -R^T T`` (the paper's Eq. (13)), in the rig's units;
- orientation: the object's rotation matrix ``M`` (object -> world) as XYZ Euler angles by Eq. (14);
- a perspective camera (``lens``, ``sensor_width``, horizontal sensor fit, ``shift_x``, ``shift_y``), or for the
  projector a spot light whose cone (``spot_size``) holds the whole projector image.

Convention: OpenCV's (and Bouguet's) camera looks down its +Z axis with +X right and +Y down the image; Blender's
camera and spot light look down their local -Z axis with +X right and +Y up. The same physical device is
therefore ``M = R^T @ diag(1, -1, -1)``: the columns of ``R^T`` are the device axes in world coordinates, and
Blender's local Y and Z are OpenCV's negated. Blender's Euler mode ``'XYZ'`` composes
``M = Rz(phi) @ Ry(theta) @ Rx(psi)`` (x first), which is exactly what Eq. (14) (Slabaugh's decomposition)
inverts: ``psi = atan2(m32, m33)``, ``theta = atan2(-m31, sqrt(m32^2 + m33^2))``, ``phi = atan2(m21, m11)``.
Table 1 writes the single-argument ``arctan(r32/r33)`` etc. of ``R^T``; flipping two columns does not change
those ratios, so for angles within +-90 deg Table 1 gives the same numbers as ``atan2`` on ``M`` (pinned by a
test on the DP-TPU calibration); ``atan2`` also keeps the quadrant beyond that.

Blender's pinhole (``sensor_fit='HORIZONTAL'``): focal length in pixels ``f = lens / sensor_width * W``; the
principal point, 0-based (docs/architecture.md), is ``cx = W/2 - 0.5 - shift_x W`` and ``cy = H/2 - 0.5 + shift_y W``
(both shifts are fractions of the fitted dimension, the width; Blender's image y grows upwards). What Blender's
camera cannot represent: skew (``K[0, 1]``), unequal focal lengths ``fx != fy`` (only through the render's pixel
aspect, which changes the pixel grid) and lens distortion. :mod:`dptpu.sim.blender` therefore renders an ideal
square-pixel pinhole image and resamples it into the real camera (:mod:`dptpu.sim.blender.camera_warp`); the
projector has no such limit, because its pattern is looked up through the full model (``K`` with skew and
``fx != fy``, distortion) in the light's shader nodes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.fpp.distortion import pixels_to_normalized, undistort

__all__ = ["BlenderCamera", "BlenderProjector", "blender_rotation", "camera_parameters", "euler_xyz_from_matrix",
           "matrix_from_euler_xyz", "project_blender_camera", "projector_parameters", "spot_size_rad",
           "twin_parameters", "BLENDER_FROM_OPENCV", "DEFAULT_PIXEL_PITCH_MM"]

#: Device axes: Blender's camera/light local frame from OpenCV's (x right, y up, looking down -z).
BLENDER_FROM_OPENCV = np.diag([1.0, -1.0, -1.0])

#: Pixel pitch of the DP-TPU camera, a Basler acA640-750um (4.8 um): makes ``lens`` a real focal length in mm.
DEFAULT_PIXEL_PITCH_MM = 0.0048
#: Blender's smallest camera sensor width (smaller values are clamped silently).
_MIN_SENSOR_WIDTH_MM = 1.0


@dataclass(frozen=True)
class BlenderCamera:
    """A Blender perspective camera equivalent to a calibrated pinhole camera (the camera column of Table 1).

    Attributes
    ----------
    location : ndarray (3,)
        Camera centre ``-R^T T`` in world coordinates, rig units (Eq. (13)).
    rotation_euler : ndarray (3,)
        Blender ``rotation_euler`` in mode 'XYZ', radians: ``(psi, theta, phi)`` about x, y, z (Eq. (14)).
    matrix : ndarray (3, 3)
        The object's rotation (Blender local -> world), ``R^T @ diag(1, -1, -1)``.
    lens_mm, sensor_width_mm : float
        Focal length and sensor width (``sensor_fit='HORIZONTAL'``); only their ratio matters to the image.
    shift_x, shift_y : float
        Lens shift, fractions of the image width, from the principal point.
    resolution : (int, int)
        ``(width, height)`` pixels.
    focal_px : (float, float)
        ``(fx, fy)`` of ``K``; Blender renders ``fx`` with square pixels.
    principal_point_px : (float, float)
        ``(cx, cy)`` of ``K``, 0-based.
    skew_px : float
        ``K[0, 1]``; ``skew_factor = skew_px / fx`` (the paper's script prints it).
    """

    location: np.ndarray
    rotation_euler: np.ndarray
    matrix: np.ndarray
    lens_mm: float
    sensor_width_mm: float
    shift_x: float
    shift_y: float
    resolution: tuple[int, int]
    focal_px: tuple[float, float]
    principal_point_px: tuple[float, float]
    skew_px: float

    @property
    def skew_factor(self) -> float:
        return self.skew_px / self.focal_px[0]

    @property
    def pixel_aspect(self) -> float:
        """``fy / fx``: 1 for square pixels."""
        return self.focal_px[1] / self.focal_px[0]


@dataclass(frozen=True)
class BlenderProjector:
    """A Blender spot light that projects an image through the projector's full model (Table 1, projector column).

    Attributes
    ----------
    location, rotation_euler, matrix :
        As :class:`BlenderCamera` (the light also looks down its local -Z axis).
    spot_size_rad : float
        Full cone angle that holds every projector pixel (Blender ``spot_size``).
    K : ndarray (3, 3)
        Intrinsics with skew and ``fx != fy`` (applied in the light's shader nodes).
    dist : ndarray (5,)
        ``k1 k2 p1 p2 k3`` (applied in the light's shader nodes).
    resolution : (int, int)
        Projector ``(width, height)`` pixels.
    """

    location: np.ndarray
    rotation_euler: np.ndarray
    matrix: np.ndarray
    spot_size_rad: float
    K: np.ndarray
    dist: np.ndarray
    resolution: tuple[int, int]


def euler_xyz_from_matrix(M) -> np.ndarray:
    """Eq. (14): XYZ Euler angles ``(psi, theta, phi)`` of a rotation ``M = Rz(phi) Ry(theta) Rx(psi)``.

    Parameters
    ----------
    M : array_like (3, 3)
        Rotation matrix (Blender object -> world).

    Returns
    -------
    ndarray (3,)
        ``(psi, theta, phi)`` in radians, rotations about x, y, z (Blender ``rotation_euler``, mode 'XYZ').

    Notes
    -----
    ``psi = atan2(m32, m33)``, ``theta = atan2(-m31, sqrt(m32^2 + m33^2))``, ``phi = atan2(m21, m11)`` (1-based
    indices, Slabaugh's formula quoted by the paper). At ``theta = +-90 deg`` (gimbal lock) ``psi`` and ``phi`` are
    not unique; the result still reproduces ``M`` up to rounding only away from it.
    """
    M = _rotation(M, "M")
    psi = np.arctan2(M[2, 1], M[2, 2])
    theta = np.arctan2(-M[2, 0], np.hypot(M[2, 1], M[2, 2]))
    phi = np.arctan2(M[1, 0], M[0, 0])
    return np.array([psi, theta, phi])


def matrix_from_euler_xyz(angles) -> np.ndarray:
    """Blender's XYZ Euler rotation: ``Rz(phi) @ Ry(theta) @ Rx(psi)`` for ``angles = (psi, theta, phi)``, (3, 3)."""
    psi, theta, phi = (float(a) for a in np.ravel(angles))
    cx, sx, cy, sy, cz, sz = np.cos(psi), np.sin(psi), np.cos(theta), np.sin(theta), np.cos(phi), np.sin(phi)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def blender_rotation(device: DeviceModel) -> np.ndarray:
    """The Blender object's rotation (local -> world) of a device: ``R^T @ diag(1, -1, -1)``, (3, 3)."""
    return device.R.T @ BLENDER_FROM_OPENCV


def camera_parameters(device: DeviceModel, *, pixel_pitch_mm: float = DEFAULT_PIXEL_PITCH_MM,
                      sensor_width_mm: float | None = None) -> BlenderCamera:
    """Table 1 for a camera: a Blender perspective camera with the device's pose and pinhole.

    Parameters
    ----------
    device : DeviceModel
    pixel_pitch_mm : float
        Sensor pixel pitch; sets ``sensor_width = W * pitch`` and so ``lens = fx * pitch`` (mm).
    sensor_width_mm : float, optional
        Sensor width instead of ``W * pitch`` (``lens = fx * sensor_width / W``). Blender clamps sensor widths
        below 1 mm, so small render sizes need this (the renderer uses 36 mm).

    Returns
    -------
    BlenderCamera
        The focal length is ``fx`` with square pixels; ``fy``, skew and distortion are reported, not representable
        by the Blender camera (module docstring).
    """
    if not np.isfinite(pixel_pitch_mm) or pixel_pitch_mm <= 0:
        raise ValueError(f"pixel_pitch_mm must be a positive length in mm; got {pixel_pitch_mm}")
    width, height = device.size
    sensor = width * pixel_pitch_mm if sensor_width_mm is None else float(sensor_width_mm)
    if not np.isfinite(sensor) or sensor < _MIN_SENSOR_WIDTH_MM:
        raise ValueError(f"sensor width must be >= {_MIN_SENSOR_WIDTH_MM} mm (Blender clamps smaller ones); got "
                         f"{sensor} mm ({width} px x {pixel_pitch_mm} mm): give sensor_width_mm")
    fx, fy = float(device.K[0, 0]), float(device.K[1, 1])
    cx, cy = float(device.K[0, 2]), float(device.K[1, 2])
    if fx <= 0 or fy <= 0:
        raise ValueError(f"K must have positive focal lengths; got fx={fx}, fy={fy}")
    M = blender_rotation(device)
    return BlenderCamera(location=device.center, rotation_euler=euler_xyz_from_matrix(M), matrix=M,
                         lens_mm=fx * sensor / width, sensor_width_mm=sensor,
                         shift_x=(width / 2.0 - 0.5 - cx) / width, shift_y=(cy + 0.5 - height / 2.0) / width,
                         resolution=(int(width), int(height)), focal_px=(fx, fy), principal_point_px=(cx, cy),
                         skew_px=float(device.K[0, 1]))


def spot_size_rad(device: DeviceModel, *, margin_rad: float = 0.01) -> float:
    """Full cone angle of a spot light that holds every pixel of the device's image, radians.

    The cone must reach the projector image's outer corners ``(-0.5, -0.5)`` .. ``(W - 0.5, H - 0.5)`` after
    undistortion; ``margin_rad`` widens it slightly (the pattern itself clips at the image edge).
    """
    width, height = device.size
    corners = np.array([[-0.5, -0.5], [width - 0.5, -0.5], [-0.5, height - 0.5], [width - 0.5, height - 0.5]])
    edges = np.concatenate([corners, [[width / 2 - 0.5, -0.5], [width / 2 - 0.5, height - 0.5],
                                      [-0.5, height / 2 - 0.5], [width - 0.5, height / 2 - 0.5]]])
    xy = undistort(pixels_to_normalized(edges, device.K), device.dist)  # (8, 2)
    half = float(np.max(np.arctan(np.hypot(xy[:, 0], xy[:, 1]))))
    return min(2.0 * half + margin_rad, np.radians(179.0))


def projector_parameters(device: DeviceModel) -> BlenderProjector:
    """Table 1 for the projector: a spot light with the device's pose, a cone holding its image, and its model."""
    M = blender_rotation(device)
    return BlenderProjector(location=device.center, rotation_euler=euler_xyz_from_matrix(M), matrix=M,
                            spot_size_rad=spot_size_rad(device), K=device.K.copy(), dist=device.dist.copy(),
                            resolution=(int(device.size[0]), int(device.size[1])))


def project_blender_camera(camera: BlenderCamera, points_world) -> np.ndarray:
    """Pixels of world points through Blender's camera model (what Blender renders), (N, 3) -> (N, 2).

    Implements Blender's own conventions (object matrix from ``rotation_euler``, local -Z forward, +Y up,
    horizontal sensor fit, shifts in widths) to pin :func:`camera_parameters` against OpenCV's projection.
    Returns 0-based pixel coordinates ``(u, v)`` (u right, v down).
    """
    points = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    M = matrix_from_euler_xyz(camera.rotation_euler)
    local = (points - camera.location) @ M  # (N, 3): M^T (X - location), Blender camera frame
    width, height = camera.resolution
    f_px = camera.lens_mm / camera.sensor_width_mm * width
    depth = -local[:, 2]  # in front of the camera: local z < 0
    # view plane, pixels from the optical axis (x right, y up), then the window shifted by shift * width
    x_plane, y_plane = f_px * local[:, 0] / depth, f_px * local[:, 1] / depth
    u = x_plane + width / 2.0 - camera.shift_x * width - 0.5
    v = height / 2.0 + camera.shift_y * width - y_plane - 0.5
    return np.stack([u, v], axis=-1)


def twin_parameters(rig: Rig, *, pixel_pitch_mm: float = DEFAULT_PIXEL_PITCH_MM) -> dict:
    """The Blender parameters of Table 1 for both devices, as plain numbers (JSON-ready).

    Returns
    -------
    dict
        ``{"units": ..., "camera": {...}, "projector": {...}}``; angles in degrees and radians, locations in the rig's
        units and in metres, focal lengths in pixels (and mm for the camera), principal points, skew and what the
        renderer does about what Blender cannot represent.
    """
    camera = camera_parameters(rig.camera, pixel_pitch_mm=pixel_pitch_mm)
    projector = projector_parameters(rig.projector)
    scale = rig.scale_to_m

    def pose(entry) -> dict:
        return {"location": [float(v) for v in entry.location],
                "location_m": [float(v) * scale for v in entry.location],
                "rotation_euler_deg": [float(np.degrees(a)) for a in entry.rotation_euler],
                "rotation_euler_rad": [float(a) for a in entry.rotation_euler],
                "rotation_mode": "XYZ"}

    K_p = rig.projector.K
    return {
        "units": rig.units,
        "camera": {
            **pose(camera), "type": "PERSP", "lens_mm": camera.lens_mm, "sensor_width_mm": camera.sensor_width_mm,
            "sensor_fit": "HORIZONTAL", "pixel_pitch_mm": pixel_pitch_mm,
            "resolution": list(camera.resolution),
            "focal_length_px": list(camera.focal_px), "pixel_aspect_fy_over_fx": camera.pixel_aspect,
            "principal_point_px": list(camera.principal_point_px),
            "shift_x": camera.shift_x, "shift_y": camera.shift_y,
            "skew_px": camera.skew_px, "skew_factor": camera.skew_factor,
            "distortion": [float(v) for v in rig.camera.dist],
            "not_in_blender": "skew, fy != fx and distortion: rendered as an ideal square-pixel pinhole, "
                              "then resampled into the real camera",
        },
        "projector": {
            **pose(projector), "type": "SPOT", "spot_size_rad": projector.spot_size_rad,
            "spot_size_deg": float(np.degrees(projector.spot_size_rad)), "spot_blend": 0.0,
            "resolution": list(projector.resolution),
            "focal_length_px": [float(K_p[0, 0]), float(K_p[1, 1])],
            "principal_point_px": [float(K_p[0, 2]), float(K_p[1, 2])],
            "skew_px": float(K_p[0, 1]), "skew_factor": float(K_p[0, 1] / K_p[0, 0]),
            "distortion": [float(v) for v in rig.projector.dist],
            "not_in_blender": "none: the pattern is looked up through K (skew, fx != fy) and the distortion in "
                              "the light's shader nodes",
        },
    }


def _rotation(M, name) -> np.ndarray:
    M = np.asarray(M, dtype=np.float64)
    if M.shape != (3, 3):
        raise ValueError(f"{name} must be a rotation matrix of shape (3, 3); got {M.shape}")
    if not np.allclose(M @ M.T, np.eye(3), atol=1e-6) or np.linalg.det(M) < 0:
        raise ValueError(f"{name} must be a rotation matrix (orthonormal, det +1)")
    return M

