"""The files a rig (:mod:`dptpu.fpp.rig_model`: a camera and a projector, an inverse camera) is read from and
written to.

One model serves every reader: each device has ``K`` (3x3 intrinsics, skew allowed), ``dist`` (Brown-Conrady
k1 k2 p1 p2 k3, OpenCV order), ``R``, ``T`` (world to device: ``X_dev = R @ X_world + T``) and ``size``
(width, height) in pixels. Units of ``T`` are the rig's declared ``units`` (the DP-TPU sphere data: mm).

Readers:

- Bouguet camera-calibration-toolbox ``.mat`` files (``KK``, ``kc``, ``Rc_<n>``, ``Tc_<n>``): the extrinsics
  of calibration pose ``n`` (default 1) define the world frame, as in the DP-TPU data;
- OpenCV FileStorage YAML, either one rig file (``cam_K``, ``cam_kc``, ``proj_K``, ``proj_kc``, ``R``,
  ``T`` as written by projector-camera calibration tools, world = camera frame; our writer adds ``cam_R``,
  ``cam_T``, ``cam_size``, ``proj_size``, ``units``) or one file per device (``camera_matrix``,
  ``distortion_coefficients``, ``image_width``, ``image_height``, optional ``R`` or ``rvec`` and ``T``);
- ``dptpu-rig/1`` YAML (docs/architecture.md), with the optional ``projector.phase_response`` (the projector's
  harmonic phase error per step count, :class:`dptpu.fpp.phase_harmonics.ProjectorPhaseResponse`; written by
  ``dptpu calibrate response``, docs/calibration.md). A file without it is read as before; a reader that predates
  it ignores it (the devices take unknown keys), so the format stays ``dptpu-rig/1``.

Writers: ``dptpu-rig/1`` YAML and the OpenCV FileStorage rig file.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import yaml

from .checks import is_finite_real
from .mat_file import read_mat
from .phase_harmonics import HarmonicPhaseError, ProjectorPhaseResponse
from .rig_model import METRES_PER_UNIT, DeviceModel, Rig, checked_array
from .text_files import read_text_file

__all__ = ["PHASE_RESPONSE_KEY", "RIG_FORMAT", "DeviceModel", "Rig", "check_physical_device", "check_physical_rig",
           "load_bouguet", "load_bouguet_pair", "load_device", "load_opencv_device", "load_opencv_rig", "load_rig",
           "phase_response_from_dict", "phase_response_to_dict", "save_opencv_rig", "save_rig"]

RIG_FORMAT = "dptpu-rig/1"
#: Largest width or height of a device, pixels (no camera or projector panel comes near it).
MAX_SIDE_PX = 100_000
#: Largest focal length as a multiple of the device's larger side (a field of view of about 0.06 degrees).
MAX_FOCAL_PER_SIDE = 1000.0
#: Largest magnitude of a distortion coefficient (real lenses stay far below; beyond it the model is noise).
MAX_DISTORTION = 1000.0
#: Largest distance of a device from the world origin, metres (a bench-top or robot rig is within metres).
MAX_DISTANCE_M = 1000.0


# --- physical plausibility ------------------------------------------------------------------------------

def check_physical_device(device: DeviceModel, where: str) -> DeviceModel:
    """Refuse a device no lens and panel can have: non-positive or absurd focal lengths, a principal point far
    off the panel, absurd distortion or size. ``where`` (e.g. ``"rig.yaml: camera"``) starts the message.

    Raises
    ------
    ValueError
        Naming the field, its value and the range expected.
    """
    width, height = device.size
    side = max(width, height)
    if side > MAX_SIDE_PX:
        raise ValueError(f"{where}.size must be at most {MAX_SIDE_PX} pixels a side; got {list(device.size)}")
    K = device.K
    for name, value in (("fx (K[0][0])", K[0, 0]), ("fy (K[1][1])", K[1, 1])):
        if not 0 < value <= MAX_FOCAL_PER_SIDE * side:
            raise ValueError(f"{where}: focal length {name} must be in (0, {MAX_FOCAL_PER_SIDE:g} x the larger side "
                             f"= {MAX_FOCAL_PER_SIDE * side:g}] pixels; got {value:g}")
    if abs(K[0, 1]) > K[0, 0]:
        raise ValueError(f"{where}: skew K[0][1] must be at most fx = {K[0, 0]:g} in magnitude; got {K[0, 1]:g}")
    for name, value, extent in (("cx (K[0][2])", K[0, 2], width), ("cy (K[1][2])", K[1, 2], height)):
        if not -extent <= value <= 2 * extent:
            raise ValueError(f"{where}: principal point {name} must lie within one panel size of the panel, "
                             f"[{-extent}, {2 * extent}] pixels; got {value:g}")
    if np.any(np.abs(device.dist) > MAX_DISTORTION):
        raise ValueError(f"{where}: distortion coefficients (k1 k2 p1 p2 k3) must be within +-{MAX_DISTORTION:g}; "
                         f"got {device.dist.tolist()}")
    return device


def check_physical_rig(rig: Rig, source) -> Rig:
    """:func:`check_physical_device` for both devices, known ``units``, devices within :data:`MAX_DISTANCE_M` of
    the origin and apart (a baseline > 0: coinciding centres cannot triangulate). ``source`` names the file."""
    if rig.units not in METRES_PER_UNIT:
        raise ValueError(f"{source}: units must be one of {', '.join(METRES_PER_UNIT)}; got {rig.units!r}")
    for name in ("camera", "projector"):
        device = check_physical_device(getattr(rig, name), f"{source}: {name}")
        with np.errstate(over="ignore"):  # an absurd T overflows to inf, which the check refuses
            distance_m = float(np.linalg.norm(device.center)) * rig.scale_to_m
        if not distance_m <= MAX_DISTANCE_M:
            raise ValueError(f"{source}: {name} centre -R^T T lies {distance_m:g} m from the world origin; expected at "
                             f"most {MAX_DISTANCE_M:g} m (is T in {rig.units}?)")
    with np.errstate(over="ignore", invalid="ignore"):
        baseline = float(np.linalg.norm(rig.camera.center - rig.projector.center))
    if not baseline > 0:
        raise ValueError(f"{source}: camera and projector centres coincide (baseline 0 {rig.units}); a rig needs the "
                         f"projector beside the camera to triangulate")
    return rig


# --- Bouguet toolbox ------------------------------------------------------------------------------------

def load_bouguet(path, size, *, pose: int = 1) -> DeviceModel:
    """Read one device from a Bouguet camera-calibration-toolbox ``.mat`` file.

    Parameters
    ----------
    path : path-like
        ``Calib_Results.mat``-style file with ``KK``, ``kc``, ``Rc_<pose>``, ``Tc_<pose>``.
    size : (int, int)
        ``(width, height)`` of the device in pixels (the toolbox stores ``nx``, ``ny`` too; they are used when
        ``size`` is None).
    pose : int
        Calibration pose whose extrinsics define the world frame (1-based, as in the toolbox).
    """
    path = Path(path)
    data = read_mat(path, what="calibration file")
    fields = {"KK": (3, 3), "kc": None, f"Rc_{pose}": (3, 3), f"Tc_{pose}": None}
    for name, shape in fields.items():
        if name not in data:
            raise ValueError(f"{path}: missing field '{name}' (a Bouguet calibration needs KK, kc, Rc_{pose}, "
                             f"Tc_{pose})")
        if shape is not None and np.shape(data[name]) != shape:
            raise ValueError(f"{path}: field '{name}' must have shape {shape}; got {np.shape(data[name])}")
    if size is None:
        if "nx" not in data or "ny" not in data:
            raise ValueError(f"{path}: no image size given and the file has no 'nx'/'ny' fields")
        size = (int(np.ravel(data["nx"])[0]), int(np.ravel(data["ny"])[0]))
    try:
        return DeviceModel(K=data["KK"], dist=np.ravel(data["kc"]), R=data[f"Rc_{pose}"],
                           T=np.ravel(data[f"Tc_{pose}"]), size=size)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def load_bouguet_pair(camera_path, projector_path, *, camera_size=None, projector_size=None, pose=1,
                      units="mm", relative_pose: str = "view") -> Rig:
    """A rig from the Bouguet camera and projector files of one calibration.

    Parameters
    ----------
    relative_pose : {"view", "all-views"}
        "view": both devices take the extrinsics of calibration view ``pose`` (the toolbox's, and the DP-TPU
        paper's, choice). "all-views": the camera keeps view ``pose`` as the world frame and the projector's pose
        relative to the camera is refined over every active view of both files
        (:func:`dptpu.fpp.stereo_calibration.refine_relative_pose`).
    """
    camera = load_bouguet(camera_path, camera_size, pose=pose)
    projector = load_bouguet(projector_path, projector_size, pose=pose)
    if relative_pose == "all-views":
        projector = _projector_from_all_views(camera_path, projector_path, camera, projector)
    elif relative_pose != "view":
        raise ValueError(f"relative_pose must be 'view' or 'all-views'; got {relative_pose!r}")
    return check_physical_rig(Rig(camera=camera, projector=projector, units=units), f"{camera_path} + {projector_path}")


def _projector_from_all_views(camera_path, projector_path, camera: DeviceModel,
                              projector: DeviceModel) -> DeviceModel:
    # scipy (least squares): heavy to import, and only this option needs it
    from .stereo_calibration import CalibrationViews, refine_relative_pose

    camera_data = read_mat(camera_path, what="calibration file")
    projector_data = read_mat(projector_path, what="calibration file")
    active = np.ravel(camera_data.get("active_images", np.ones((1, 0)))).astype(bool)
    views = [k + 1 for k in np.flatnonzero(active)]
    object_points, camera_points, projector_points, boards = [], [], [], []
    for k in views:
        for data, path in ((camera_data, camera_path), (projector_data, projector_path)):
            for name in (f"X_{k}", f"x_{k}", f"Rc_{k}", f"Tc_{k}"):
                if name not in data:
                    raise ValueError(f"{path}: missing field '{name}' (needed for relative_pose='all-views')")
        if not np.array_equal(camera_data[f"X_{k}"], projector_data[f"X_{k}"]):
            raise ValueError(f"{camera_path} and {projector_path}: view {k} has different board points X_{k}")
        object_points.append(np.asarray(camera_data[f"X_{k}"], dtype=np.float64).T)
        camera_points.append(np.asarray(camera_data[f"x_{k}"], dtype=np.float64).T)
        projector_points.append(np.asarray(projector_data[f"x_{k}"], dtype=np.float64).T)
        boards.append((camera_data[f"Rc_{k}"], np.ravel(camera_data[f"Tc_{k}"])))
    if not views:
        raise ValueError(f"{camera_path}: no active calibration views")
    R_start = projector.R @ camera.R.T
    relative = refine_relative_pose(camera, projector, CalibrationViews(object_points, camera_points,
                                                                        projector_points),
                                    initial_board_poses=boards,
                                    initial_relative=(R_start, projector.T - R_start @ camera.T))
    return DeviceModel(K=projector.K, dist=projector.dist, R=relative.R @ camera.R,
                       T=relative.R @ camera.T + relative.T, size=projector.size)


# --- dptpu-rig/1 YAML ----------------------------------------------------------------------------------

def _device_to_dict(device: DeviceModel) -> dict:
    return {"size": list(device.size), "K": device.K.tolist(), "dist": device.dist.tolist(),
            "R": device.R.tolist(), "T": device.T.tolist()}


def _device_from_dict(entry, where: str) -> DeviceModel:
    if not isinstance(entry, dict):
        raise ValueError(f"{where} must be a mapping with size, K, dist, R, T")
    for key in ("size", "K", "dist", "R", "T"):
        if key not in entry:
            raise ValueError(f"{where}: missing key '{key}'")
    dist, size = entry["dist"], entry["size"]
    if not isinstance(dist, list) or len(dist) not in (4, 5) or not all(is_finite_real(v) for v in dist):
        raise ValueError(f"{where}.dist must be a list of 4 or 5 finite numbers [k1, k2, p1, p2, k3]; got {dist!r}")
    if (not isinstance(size, list) or len(size) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and 0 < v <= MAX_SIDE_PX for v in size)):
        raise ValueError(f"{where}.size must be [width, height], two integers in [1, {MAX_SIDE_PX}] pixels; "
                         f"got {size!r}")
    try:
        return DeviceModel(K=entry["K"], dist=np.asarray(dist, dtype=np.float64), R=entry["R"], T=entry["T"],
                           size=(size[0], size[1]))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{where}: {exc}") from None


#: The key of the projector's phase response in a ``dptpu-rig/1`` file, and the keys of one step count's entry.
PHASE_RESPONSE_KEY = "phase_response"
_RESPONSE_TERMS = ("cos_rad", "sin_rad")
#: Step counts a phase response may hold (a capture's ``steps`` range, docs/capture-format.md).
_RESPONSE_STEPS = (3, 1000)


def phase_response_to_dict(response: ProjectorPhaseResponse) -> dict:
    """``{N: {cos_rad: a, sin_rad: b}}`` (ascending ``N``; lists ``[a_1, a_2, ...]`` for the terms at ``N, 2N, ...``
    when an error has more than the first): the YAML of ``projector.phase_response``."""
    document = {}
    for steps in response.steps:
        terms = response.errors[steps].terms
        cosines, sines = [c for _, c, _ in terms], [s for _, _, s in terms]
        document[steps] = ({"cos_rad": cosines[0], "sin_rad": sines[0]} if len(terms) == 1
                           else {"cos_rad": cosines, "sin_rad": sines})
    return document


def phase_response_from_dict(entry, where: str) -> ProjectorPhaseResponse:
    """Check and read ``projector.phase_response``; ``where`` (e.g. ``"rig.yaml: projector.phase_response"``)
    starts every message.

    Raises
    ------
    ValueError
        Not a mapping of step counts (integers in [3, 1000]) to ``{cos_rad, sin_rad}`` of finite numbers (or of
        equally long lists of them: the terms at ``N, 2N, ...``), or an error too large to invert (its slope
        reaching -1: ``steps x amplitude >= 1`` for one term).
    """
    expected = "a mapping of step counts to {cos_rad: R, sin_rad: R}, e.g. {3: {cos_rad: 0.01, sin_rad: -0.16}}"
    if not isinstance(entry, dict) or not entry:
        raise ValueError(f"{where} must be {expected}; got {entry!r}")
    errors = {}
    low, high = _RESPONSE_STEPS
    for steps, terms in entry.items():
        if isinstance(steps, bool) or not isinstance(steps, int) or not low <= steps <= high:
            raise ValueError(f"{where}: keys are step counts, integers in [{low}, {high}]; got {steps!r}")
        if not isinstance(terms, dict) or set(terms) != set(_RESPONSE_TERMS):
            raise ValueError(f"{where}[{steps}] must be {{cos_rad: R, sin_rad: R}} (radians); got {terms!r}")
        values = {}
        for name in _RESPONSE_TERMS:
            value = terms[name]
            listed = value if isinstance(value, list) else [value]
            if not listed or not all(is_finite_real(v) for v in listed):
                raise ValueError(f"{where}[{steps}].{name} must be a finite number or a list of them (radians, the "
                                 f"terms at {steps}, {2 * steps}, ... times the phase); got {value!r}")
            values[name] = [float(v) for v in listed]
        if len(values["cos_rad"]) != len(values["sin_rad"]):
            raise ValueError(f"{where}[{steps}]: cos_rad and sin_rad must list as many terms; got "
                             f"{len(values['cos_rad'])} and {len(values['sin_rad'])}")
        cosines, sines = values["cos_rad"], values["sin_rad"]
        error = HarmonicPhaseError(steps=steps, cos_rad=cosines[0], sin_rad=sines[0],
                                   higher_cos_rad=tuple(cosines[1:]), higher_sin_rad=tuple(sines[1:]))
        if not error.min_slope > -1.0:
            raise ValueError(f"{where}[{steps}]: the error's slope must stay above -1 (for one term: amplitude below "
                             f"1 / {steps} = {1.0 / steps:.4g} rad); got {error.min_slope:.4g} (amplitude "
                             f"{error.amplitude_rad:.4g} rad): a larger harmonic phase error cannot be inverted")
        errors[steps] = error
    return ProjectorPhaseResponse(errors)


def save_rig(rig: Rig, path) -> Path:
    """Write ``rig`` as a ``dptpu-rig/1`` YAML file (with ``projector.phase_response`` when it has one); returns the
    path."""
    path = Path(path)
    projector = _device_to_dict(rig.projector)
    if rig.phase_response is not None and rig.phase_response.steps:
        projector[PHASE_RESPONSE_KEY] = phase_response_to_dict(rig.phase_response)
    document = {"format": RIG_FORMAT, "units": rig.units, "camera": _device_to_dict(rig.camera),
                "projector": projector, "effects": list(rig.effects)}
    path.write_text(yaml.safe_dump(document, sort_keys=False, default_flow_style=None))
    return path


def load_rig(path) -> Rig:
    """Read a rig file: ``dptpu-rig/1`` YAML or an OpenCV FileStorage rig file (detected by content)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such rig file")
    if not path.is_file():
        raise ValueError(f"{path}: a rig file must be a file (dptpu-rig/1 or OpenCV FileStorage YAML); got a folder")
    text = read_text_file(path, "a rig file (dptpu-rig/1 or OpenCV FileStorage YAML)")
    if text.lstrip().startswith("%YAML:1.0") or "!!opencv-matrix" in text:
        return load_opencv_rig(path)
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({' '.join(str(exc).split())})") from None
    if not isinstance(document, dict):
        raise ValueError(f"{path}: a rig file must be a mapping with format: {RIG_FORMAT}")
    if document.get("format") != RIG_FORMAT:
        raise ValueError(f"{path}: format must be '{RIG_FORMAT}'; got {document.get('format')!r}")
    for key in ("camera", "projector"):
        if key not in document:
            raise ValueError(f"{path}: missing key '{key}'")
    effects = document.get("effects") or []
    if not isinstance(effects, list):
        raise ValueError(f"{path}: 'effects' must be a list; got {type(effects).__name__}")
    projector = document["projector"]
    response = None
    if isinstance(projector, dict) and projector.get(PHASE_RESPONSE_KEY) is not None:
        response = phase_response_from_dict(projector[PHASE_RESPONSE_KEY], f"{path}: projector.{PHASE_RESPONSE_KEY}")
    rig = Rig(camera=_device_from_dict(document["camera"], f"{path}: camera"),
              projector=_device_from_dict(projector, f"{path}: projector"),
              units=str(document.get("units", "mm")), effects=tuple(effects), phase_response=response)
    return check_physical_rig(rig, path)


# --- OpenCV FileStorage --------------------------------------------------------------------------------

def _read_node(storage, name, path, *, required=True):
    node = storage.getNode(name)
    if node.empty():
        if required:
            raise ValueError(f"{path}: missing field '{name}'")
        return None
    if node.isMap() or node.isSeq():
        if node.isSeq():
            return np.array([node.at(i).real() for i in range(node.size())])
        return node.mat()
    if node.isString():
        return node.string()
    return node.real() if node.isReal() or node.isInt() else node.mat()


def _open_storage(path):
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error as exc:
        raise ValueError(f"{path}: not an OpenCV FileStorage file ({exc.err})") from None
    if not storage.isOpened():
        raise ValueError(f"{path}: not an OpenCV FileStorage file")
    return storage


def load_opencv_rig(path, *, camera_size=None, projector_size=None, units=None) -> Rig:
    """Read an OpenCV FileStorage rig file (``cam_K``, ``cam_kc``, ``proj_K``, ``proj_kc``, ``R``, ``T``; optional
    ``proj_phase_response``, rows ``[steps, cos_1, sin_1, cos_2, sin_2, ...]``: the rig's ``phase_response``).

    ``R``, ``T`` map camera coordinates to projector coordinates. ``cam_R``/``cam_T`` (optional, identity and
    zero by default) place the camera in the world. Sizes come from ``cam_size``/``proj_size`` or the
    arguments.
    """
    storage = _open_storage(path)
    try:
        cam_K = _read_node(storage, "cam_K", path)
        cam_kc = _read_node(storage, "cam_kc", path)
        proj_K = _read_node(storage, "proj_K", path)
        proj_kc = _read_node(storage, "proj_kc", path)
        R_cp = _read_node(storage, "R", path)
        T_cp = _read_node(storage, "T", path)
        cam_R = _read_node(storage, "cam_R", path, required=False)
        cam_T = _read_node(storage, "cam_T", path, required=False)
        cam_size = _read_node(storage, "cam_size", path, required=False)
        proj_size = _read_node(storage, "proj_size", path, required=False)
        file_units = _read_node(storage, "units", path, required=False)
        response_rows = _read_node(storage, "proj_phase_response", path, required=False)
    finally:
        storage.release()
    response = None if response_rows is None else _phase_response_from_rows(response_rows, path)
    camera_size = camera_size or (None if cam_size is None else tuple(np.ravel(cam_size).astype(int)))
    projector_size = projector_size or (None if proj_size is None else tuple(np.ravel(proj_size).astype(int)))
    if camera_size is None or projector_size is None:
        raise ValueError(f"{path}: no 'cam_size'/'proj_size' fields; give the camera and projector sizes")
    cam_R = np.eye(3) if cam_R is None else cam_R
    cam_T = np.zeros(3) if cam_T is None else np.ravel(cam_T)
    try:
        R_cp = checked_array(R_cp, (3, 3), "R")
        T_cp = checked_array(T_cp, (3,), "T")
        camera = DeviceModel(K=cam_K, dist=np.ravel(cam_kc), R=cam_R, T=cam_T, size=camera_size)
        projector = DeviceModel(K=proj_K, dist=np.ravel(proj_kc), R=R_cp @ camera.R,
                                T=R_cp @ camera.T + T_cp, size=projector_size)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return check_physical_rig(Rig(camera=camera, projector=projector, units=units or file_units or "mm",
                                  phase_response=response), path)


def _phase_response_from_rows(rows, path) -> ProjectorPhaseResponse:
    """``proj_phase_response`` of an OpenCV rig file: one row ``[steps, cos_1, sin_1, cos_2, sin_2, ...]`` per step
    count (the terms at ``N, 2N, ...``; trailing zero pairs pad the shorter rows)."""
    array = np.asarray(rows, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] < 3 or array.shape[1] % 2 != 1 or not np.all(np.isfinite(array)):
        raise ValueError(f"{path}: proj_phase_response must be a matrix of finite rows [steps, cos_1, sin_1, cos_2, "
                         f"sin_2, ...]; got shape {array.shape}")
    entry = {}
    for row in array:
        steps = row[0]
        if steps != int(steps):
            raise ValueError(f"{path}: proj_phase_response: steps must be integers; got {steps:g}")
        pairs = row[1:].reshape(-1, 2)
        while len(pairs) > 1 and not np.any(pairs[-1]):
            pairs = pairs[:-1]
        entry[int(steps)] = {"cos_rad": pairs[:, 0].tolist(), "sin_rad": pairs[:, 1].tolist()}
    return phase_response_from_dict(entry, f"{path}: proj_phase_response")


def save_opencv_rig(rig: Rig, path) -> Path:
    """Write ``rig`` as an OpenCV FileStorage YAML rig file (readable by :func:`load_opencv_rig`)."""
    path = Path(path)
    R_cp = rig.projector.R @ rig.camera.R.T
    T_cp = rig.projector.T - R_cp @ rig.camera.T
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    try:
        storage.write("units", rig.units)
        for name, value in (("cam_K", rig.camera.K), ("cam_kc", rig.camera.dist[:, None]),
                            ("proj_K", rig.projector.K), ("proj_kc", rig.projector.dist[:, None]),
                            ("R", R_cp), ("T", T_cp[:, None]), ("cam_R", rig.camera.R),
                            ("cam_T", rig.camera.T[:, None]),
                            ("cam_size", np.array(rig.camera.size, dtype=np.float64)[:, None]),
                            ("proj_size", np.array(rig.projector.size, dtype=np.float64)[:, None])):
            storage.write(name, np.ascontiguousarray(value, dtype=np.float64))
        if rig.phase_response is not None and rig.phase_response.steps:
            response = rig.phase_response
            width = 1 + 2 * max(len(response.errors[n].terms) for n in response.steps)
            rows = np.zeros((len(response.steps), width))  # (K, 1 + 2 terms): steps, cos_1, sin_1, cos_2, ...
            for row, steps in zip(rows, response.steps):
                terms = np.asarray([[c, s] for _, c, s in response.errors[steps].terms]).ravel()
                row[0], row[1:1 + terms.size] = steps, terms
            storage.write("proj_phase_response", rows)
    finally:
        storage.release()
    return path


def load_opencv_device(path, *, size=None) -> DeviceModel:
    """Read one device from an OpenCV calibration file (``camera_matrix``, ``distortion_coefficients``,
    ``image_width``, ``image_height``; optional world pose ``R`` or ``rvec``, and ``T``/``tvec``)."""
    storage = _open_storage(path)
    try:
        K = _read_node(storage, "camera_matrix", path)
        dist = _read_node(storage, "distortion_coefficients", path)
        width = _read_node(storage, "image_width", path, required=size is None)
        height = _read_node(storage, "image_height", path, required=size is None)
        R = _read_node(storage, "R", path, required=False)
        rvec = _read_node(storage, "rvec", path, required=False)
        T = _read_node(storage, "T", path, required=False)
        if T is None:
            T = _read_node(storage, "tvec", path, required=False)
    finally:
        storage.release()
    if R is None:
        R = np.eye(3) if rvec is None else cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))[0]
    dist = np.ravel(dist)[:5]
    try:
        return DeviceModel(K=K, dist=dist, R=R, T=np.zeros(3) if T is None else np.ravel(T),
                           size=size or (int(width), int(height)))
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def load_device(path, *, size=None, pose=1) -> DeviceModel:
    """One device from a Bouguet ``.mat`` or an OpenCV FileStorage file, by extension."""
    path = Path(path)
    if path.suffix.lower() == ".mat":
        return load_bouguet(path, size, pose=pose)
    return load_opencv_device(path, size=size)
