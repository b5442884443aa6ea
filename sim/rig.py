"""The twin's rig: camera and projector models read from a calibration, resized for fast renders.

The twin renders exactly the rig model of :mod:`dptpu.fpp.calibration` (``K``, Brown-Conrady ``dist``, world to
device ``R``, ``T``, ``size``): the camera ray of each pixel goes through the camera model with its distortion,
and each hit point goes through the projector model with its distortion (the paper's Eq. (10) with the lens
model of Table 1). Sources:

- a ``dptpu-rig/1`` YAML file or an OpenCV FileStorage rig file (:func:`dptpu.fpp.calibration.load_rig`);
- a Bouguet toolbox pair ``"CAM.mat,PRJ.mat"`` (or a 2-tuple), camera 640x480 and projector 912x1140 by default
  (the DP-TPU rig);
- ``"nominal"``: :func:`nominal_rig`, a DP-TPU-like rig built from round numbers (no data needed);
- ``"dynamic"``: :func:`dynamic_rig`, the paper's second ("dynamic", unseen) rig from its published numbers;
- ``"wide"``: :func:`wide_rig`, a training rig whose camera sees the whole projector width (every fringe order).

Convention: pixel centres are 0-based (docs/architecture.md); resizing the camera keeps the image's outer edges
fixed, so pixel ``u`` of the original maps to ``(u + 0.5) * s - 0.5`` of the resized image.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from dptpu.fpp.calibration import (
    DeviceModel,
    Rig,
    load_bouguet_pair,
    load_opencv_rig,
    load_rig,
)

__all__ = [
    "DEFAULT_CAMERA_SIZE",
    "DEFAULT_PROJECTOR_SIZE",
    "DYNAMIC_PROJECTOR_SIZE",
    "RIG_PRESETS",
    "dynamic_rig",
    "load_twin_rig",
    "nominal_rig",
    "parse_size",
    "resize_camera",
    "wide_rig",
    "working_distance",
    "working_point",
]

#: The DP-TPU rig: Basler acA640-750um camera and DLP4500 projector, (width, height) pixels.
DEFAULT_CAMERA_SIZE = (640, 480)
DEFAULT_PROJECTOR_SIZE = (912, 1140)
#: The paper's dynamic rig: an XGA DMD, (width, height) pixels.
DYNAMIC_PROJECTOR_SIZE = (1024, 768)


def load_twin_rig(source, *, camera_size=None, projector_size=None, size=None) -> Rig:
    """The twin's rig from a rig file, a Bouguet pair or ``"nominal"``.

    Parameters
    ----------
    source : str, path-like, tuple of two paths, or Rig
        ``dptpu-rig/1`` or OpenCV rig file; ``"CAM.mat,PRJ.mat"`` or ``(CAM.mat, PRJ.mat)`` (Bouguet toolbox, world
        frame = calibration view 1); ``"nominal"`` (:func:`nominal_rig`), ``"dynamic"`` (:func:`dynamic_rig`) or
        ``"wide"`` (:func:`wide_rig`); a :class:`Rig` is passed through.
    camera_size, projector_size : (int, int), optional
        ``(width, height)`` of the devices when the source does not hold them (Bouguet files, OpenCV rig files
        without ``cam_size``/``proj_size``); default 640x480 and 912x1140.
    size : (int, int) or str, optional
        Render size ``(width, height)`` or ``"WxH"``: the camera ``K`` is rescaled (:func:`resize_camera`).

    Returns
    -------
    Rig
    """
    camera_size = tuple(camera_size or DEFAULT_CAMERA_SIZE)
    projector_size = tuple(projector_size or DEFAULT_PROJECTOR_SIZE)
    if isinstance(source, Rig):
        rig = source
    elif isinstance(source, (tuple, list)):
        if len(source) != 2:
            raise ValueError(f"a Bouguet rig is a pair (CAM.mat, PRJ.mat); got {len(source)} paths")
        rig = load_bouguet_pair(source[0], source[1], camera_size=camera_size, projector_size=projector_size)
    else:
        text = str(source)
        if text in RIG_PRESETS:
            rig = RIG_PRESETS[text]()
        elif "," in text:
            parts = [p.strip() for p in text.split(",")]
            if len(parts) != 2 or not all(parts):
                raise ValueError(f"a Bouguet rig is given as 'CAM.mat,PRJ.mat'; got {text!r}")
            rig = load_bouguet_pair(parts[0], parts[1], camera_size=camera_size, projector_size=projector_size)
        else:
            path = Path(text)
            if not path.exists():
                raise FileNotFoundError(f"{path}: no such rig file (give a dptpu-rig/1 or OpenCV rig file, "
                                        "'CAM.mat,PRJ.mat', 'nominal', 'dynamic' or 'wide')")
            if path.suffix.lower() == ".mat":
                raise ValueError(f"{path}: a Bouguet calibration needs both files: 'CAM.mat,PRJ.mat'")
            try:
                rig = load_rig(path)
            except ValueError as exc:
                if "cam_size" not in str(exc):
                    raise
                rig = load_opencv_rig(path, camera_size=camera_size, projector_size=projector_size)
    if size is not None:
        rig = resize_camera(rig, size)
    return rig


def parse_size(size) -> tuple[int, int]:
    """``"WxH"`` or ``(W, H)`` -> ``(W, H)``, positive integers."""
    if isinstance(size, str):
        parts = size.lower().split("x")
        try:
            values = tuple(int(p) for p in parts)
        except ValueError:
            values = ()
    else:
        values = tuple(int(v) for v in np.ravel(size))
    if len(values) != 2 or min(values) < 8:
        raise ValueError(f"size must be WIDTHxHEIGHT with both >= 8 pixels (e.g. 160x120); got {size!r}")
    return values


def resize_camera(rig: Rig, size) -> Rig:
    """The rig with its camera resampled to ``size`` (width, height): same field of view, scaled ``K``.

    ``fx, skew, cx`` scale by ``s_x = W'/W`` and ``fy, cy`` by ``s_y = H'/H`` about the image's outer edge:
    ``c' = (c + 0.5) s - 0.5`` (0-based pixel centres). Distortion, acting on normalized coordinates, is kept.
    """
    width, height = parse_size(size)
    camera = rig.camera
    sx, sy = width / camera.size[0], height / camera.size[1]
    K = camera.K.copy()
    K[0, 0] *= sx
    K[0, 1] *= sx
    K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
    K[1, 1] *= sy
    K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
    return replace(rig, camera=DeviceModel(K=K, dist=camera.dist, R=camera.R, T=camera.T, size=(width, height)))


def nominal_rig(*, camera_size=DEFAULT_CAMERA_SIZE, distance_mm: float = 800.0, angle_deg: float = 6.21) -> Rig:
    """A DP-TPU-like rig from round numbers: the world frame is the camera's, the projector sits to the camera's
    left and is turned by ``angle_deg`` (the paper's 6.21 deg between the optical axes) so that both axes cross
    at ``distance_mm`` on the camera axis.

    Intrinsics are rounded from the published twin calibration (camera f = 2600 px for 640x480, projector
    fx = 1736, fy = 3473 px for 912x1140, its principal point near the panel centre); distortion is a small
    radial ``k1``.
    """
    baseline = distance_mm * np.tan(np.radians(angle_deg))
    a = np.radians(angle_deg)
    R_p = np.array([[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]])  # axis +x turned
    centre = np.array([-baseline, 0.0, 0.0])
    camera = DeviceModel(K=np.array([[2600.0, 0.0, 319.5], [0.0, 2600.0, 239.5], [0.0, 0.0, 1.0]]),
                         dist=np.array([-0.06, 0.0, 0.0, 0.0, 0.0]),
                         R=np.eye(3), T=np.zeros(3), size=DEFAULT_CAMERA_SIZE)
    projector = DeviceModel(K=np.array([[1736.0, 0.0, 455.5], [0.0, 3473.0, 569.5], [0.0, 0.0, 1.0]]),
                            dist=np.array([-0.05, 0.0, 0.0, 0.0, 0.0]),
                            R=R_p, T=-R_p @ centre, size=DEFAULT_PROJECTOR_SIZE)
    rig = Rig(camera=camera, projector=projector, units="mm")
    return rig if tuple(camera_size) == DEFAULT_CAMERA_SIZE else resize_camera(rig, camera_size)


def dynamic_rig(*, distance_mm: float = 600.0, angle_deg: float = 10.07, focal_length_mm: float = 18.7,
                pixel_pitch_mm: float = 0.0048, camera_size=DEFAULT_CAMERA_SIZE,
                projector_focal_px: float = 5000.0) -> Rig:
    """The paper's dynamic rig (section "dynamic scenes"), unseen by the training data: a rig for tests of
    generalization.

    Published: an 18.7 mm camera lens, a 1024x768 DMD projector, a 0.12 m baseline, a 0.6 m object distance and
    10.07 deg between the camera and projector axes. Built like :func:`nominal_rig`: the world frame is the
    camera's, the projector sits to the camera's left, turned by ``angle_deg`` so both axes cross at
    ``distance_mm`` on the camera axis (where built-in and random scenes are placed).

    Parameters
    ----------
    distance_mm : float
        Working distance along the camera axis, mm (paper: 0.6 m).
    angle_deg : float
        Angle between the optical axes, degrees (paper: 10.07).
    focal_length_mm, pixel_pitch_mm : float
        Camera lens focal length and pixel pitch, mm: ``f = 18.7 / 0.0048 = 3895.8`` px. The paper's camera
        (a Phantom V611) is not otherwise specified in the paper; the pitch and the 640x480 size are the
        DP-TPU rig's camera (4.8 um, Basler acA640-750um), giving a 98.6 x 73.8 mm field at 0.6 m.
    camera_size : (int, int)
        Camera ``(width, height)``; other sizes rescale ``K`` (:func:`resize_camera`).
    projector_focal_px : float
        Projector focal length, DMD pixels (not published): 5000 px lights a 123 x 92 mm field at 0.6 m, 1.25
        times the camera's field.

    Returns
    -------
    Rig
        Units mm. The crossing-axes geometry with 0.6 m and 10.07 deg puts the projector
        ``600 * tan(10.07 deg) = 106.6`` mm from the camera, not 120 mm: the three published numbers do not
        describe one rig with crossing axes (120 mm and 10.07 deg would cross at 675 mm), so the working
        distance and the angle, which set the fringe geometry on the object, are kept.

    Notes
    -----
    Small radial distortion (camera ``k1 = -0.03``, projector ``k1 = -0.02``) differs from the nominal rig's, as
    an unseen rig's would.
    """
    a = np.radians(angle_deg)
    baseline = distance_mm * np.tan(a)
    R_p = np.array([[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]])  # axis +x turned
    centre = np.array([-baseline, 0.0, 0.0])
    f_px = focal_length_mm / pixel_pitch_mm
    width, height = DEFAULT_CAMERA_SIZE
    camera = DeviceModel(K=np.array([[f_px, 0.0, (width - 1) / 2], [0.0, f_px, (height - 1) / 2], [0.0, 0.0, 1.0]]),
                         dist=np.array([-0.03, 0.0, 0.0, 0.0, 0.0]),
                         R=np.eye(3), T=np.zeros(3), size=DEFAULT_CAMERA_SIZE)
    pw, ph = DYNAMIC_PROJECTOR_SIZE
    projector = DeviceModel(K=np.array([[projector_focal_px, 0.0, (pw - 1) / 2],
                                        [0.0, projector_focal_px, (ph - 1) / 2], [0.0, 0.0, 1.0]]),
                            dist=np.array([-0.02, 0.0, 0.0, 0.0, 0.0]),
                            R=R_p, T=-R_p @ centre, size=DYNAMIC_PROJECTOR_SIZE)
    rig = Rig(camera=camera, projector=projector, units="mm")
    return rig if tuple(camera_size) == DEFAULT_CAMERA_SIZE else resize_camera(rig, camera_size)


def wide_rig(*, distance_mm: float = 700.0, angle_deg: float = 8.0, camera_focal_px: float = 1000.0,
             camera_size=DEFAULT_CAMERA_SIZE) -> Rig:
    """A training rig whose camera sees the whole projector width, so that labels span every fringe order.

    The nominal rig's camera (f = 2600 px) sees only the middle ~47 % of the projector's width, so its samples
    never hold orders near 0 or near ``f_h - 1`` (docs/model-eval.md). This rig keeps the nominal rig's projector
    (DLP4500 intrinsics, 912x1140, ``k1 = -0.05``) and gives the camera a short lens: ``f = 1000`` px at 640x480
    (a 4.8 mm lens on 4.8 um pixels), ``k1 = -0.08``, a 700 mm working distance and 8 deg between the axes.
    At 700 mm the camera's field is 448 mm wide and the projector's 368 mm (the camera sees 122 % of the
    projector's width); a background plane at 1.12-1.25 times the distance (:func:`dptpu.sim.scenes.random_scene`)
    still shows both projector edges. It is not the unseen test rig (:func:`dynamic_rig`: 600 mm, 10.07 deg,
    f = 3896 px, a 1024x768 projector). At 320x240 a period of ``f_h = 80`` is about 3.3 camera pixels.

    Parameters
    ----------
    distance_mm : float
        Where the optical axes cross on the camera axis, mm.
    angle_deg : float
        Angle between the optical axes, degrees; the projector sits to the camera's left.
    camera_focal_px : float
        Camera focal length in pixels at 640x480.
    camera_size : (int, int)
        Camera ``(width, height)``; other sizes rescale ``K`` (:func:`resize_camera`).

    Returns
    -------
    Rig
        Units mm; world frame = the camera's.
    """
    a = np.radians(angle_deg)
    R_p = np.array([[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]])  # axis +x turned
    centre = np.array([-distance_mm * np.tan(a), 0.0, 0.0])
    f = float(camera_focal_px)
    camera = DeviceModel(K=np.array([[f, 0.0, 319.5], [0.0, f, 239.5], [0.0, 0.0, 1.0]]),
                         dist=np.array([-0.08, 0.0, 0.0, 0.0, 0.0]),
                         R=np.eye(3), T=np.zeros(3), size=DEFAULT_CAMERA_SIZE)
    projector = DeviceModel(K=np.array([[1736.0, 0.0, 455.5], [0.0, 3473.0, 569.5], [0.0, 0.0, 1.0]]),
                            dist=np.array([-0.05, 0.0, 0.0, 0.0, 0.0]),
                            R=R_p, T=-R_p @ centre, size=DEFAULT_PROJECTOR_SIZE)
    rig = Rig(camera=camera, projector=projector, units="mm")
    return rig if tuple(camera_size) == DEFAULT_CAMERA_SIZE else resize_camera(rig, camera_size)


#: Rigs that ``load_twin_rig`` (and ``--rig`` of the sim commands) builds by name.
RIG_PRESETS = {"nominal": nominal_rig, "dynamic": dynamic_rig, "wide": wide_rig}


def _principal_ray(device: DeviceModel) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3,) and unit direction (3,) in world coordinates of the device's optical axis."""
    direction = device.R.T @ np.array([0.0, 0.0, 1.0])
    return device.center, direction / np.linalg.norm(direction)


def working_point(rig: Rig) -> np.ndarray:
    """The world point (3,) midway between the camera's and the projector's optical axes where they pass closest.

    This is where both devices look: built-in scenes are placed there. When the axes are parallel, the point
    on the camera axis at the distance of the projector's centre is returned.
    """
    c1, d1 = _principal_ray(rig.camera)
    c2, d2 = _principal_ray(rig.projector)
    w = c1 - c2
    b = d1 @ d2
    denominator = 1.0 - b * b
    if denominator < 1e-10:
        return c1 + d1 * max(abs(d1 @ (c2 - c1)), 1.0)
    t1 = (b * (d2 @ w) - (d1 @ w)) / denominator
    t2 = ((d2 @ w) - b * (d1 @ w)) / denominator
    return 0.5 * ((c1 + t1 * d1) + (c2 + t2 * d2))


def working_distance(rig: Rig) -> float:
    """Depth along the camera z axis of :func:`working_point`, in the rig's units."""
    point = working_point(rig)
    return float((rig.camera.R @ point + rig.camera.T)[2])
