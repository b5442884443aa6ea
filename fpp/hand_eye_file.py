"""The hand-eye views file (``dptpu-hand-eye/1``) and the mount file ``dptpu calibrate hand-eye`` writes.

Views file: the robot's flange pose at each board capture, what the robot controller reports.

```yaml
format: dptpu-hand-eye/1
setup: eye-in-hand          # the scanner on the flange (board fixed); or eye-to-hand (scanner fixed, board on it)
base_frame: base_link       # optional (default base_link): the robot's base frame
flange_frame: tool0         # optional (default tool0): its flange frame
units: m                    # of the translations: m (default) or mm
poses:
  - capture: view_00.png            # the board seen by the scanner camera: an image (PNG, TIFF), a dptpu-capture/1
    translation: [0.41, -0.12, 0.53]  # folder (its white reference) or a calibration pose folder (x/'s white);
    quaternion: [0.0, 0.707, 0.0, 0.707]  # relative to this file. base_T_flange: translation, then the unit
  - ...                                    # quaternion [qx, qy, qz, qw] (w last, as ROS)
```

Mount file: a ROS 2 parameter file for the cloud node (``mount_frame``, ``mount_transform``; its ``/tf_static``),
what a launch file passes with ``param: [{from: mount.yaml}]`` or ``--params-file mount.yaml``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from .capture import load_reference, read_capture
from .hand_eye import SETUPS, HandEyeResult, rigid
from .scanner_frames import pose_to_xyz_quaternion

__all__ = ["FORMAT", "HandEyeViews", "read_hand_eye_views", "load_board_image", "write_mount_file"]

FORMAT = "dptpu-hand-eye/1"
_UNITS = {"m": 1.0, "mm": 1e-3}
_KEYS = {"format", "setup", "base_frame", "flange_frame", "units", "poses"}
_POSE_KEYS = {"capture", "translation", "quaternion"}
#: How far from 1 a pose quaternion's norm may be (rounded values from a controller).
_UNIT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class HandEyeViews:
    """A views file read (module docstring); ``flange_poses`` are ``base_T_flange`` 4x4 in metres."""

    path: Path
    setup: str
    base_frame: str
    flange_frame: str
    captures: tuple[Path, ...]
    flange_poses: tuple[np.ndarray, ...]


def read_hand_eye_views(path) -> HandEyeViews:
    """Read and check a ``dptpu-hand-eye/1`` views file.

    Raises
    ------
    FileNotFoundError
        The file, or a capture it names, does not exist.
    ValueError
        One line naming the file, the field and what it must be (``views.yaml: poses[2].quaternion must be 4
        numbers [qx, qy, qz, qw] of unit norm; got [0, 0, 0, 2]``).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file; expected a {FORMAT} views file")
    try:
        document = yaml.safe_load(path.read_text(encoding="utf-8-sig"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a YAML file ({' '.join(str(exc).split())})") from None
    if not isinstance(document, dict):
        raise ValueError(f"{path}: must be a mapping with format: {FORMAT}")
    if document.get("format") != FORMAT:
        raise ValueError(f"{path}: format must be {FORMAT}; got {document.get('format')!r}")
    unknown = sorted(set(document) - _KEYS)
    if unknown:
        raise ValueError(f"{path}: unknown key {unknown[0]!r} (allowed: {', '.join(sorted(_KEYS))})")
    setup = document.get("setup")
    if setup not in SETUPS:
        raise ValueError(f"{path}: setup must be one of {', '.join(SETUPS)}; got {setup!r}")
    units = document.get("units", "m")
    if units not in _UNITS:
        raise ValueError(f"{path}: units must be one of {', '.join(_UNITS)} (of the translations); got {units!r}")
    frames = {}
    for key, default in (("base_frame", "base_link"), ("flange_frame", "tool0")):
        value = document.get(key, default)
        if not isinstance(value, str) or not value or value.startswith("/") or any(c.isspace() for c in value):
            raise ValueError(f"{path}: {key} must be a TF frame id (no spaces, no leading '/'); got {value!r}")
        frames[key] = value
    poses = document.get("poses")
    if not isinstance(poses, list) or not poses:
        raise ValueError(f"{path}: poses must be a non-empty list of {{capture, translation, quaternion}}")
    captures, flange = [], []
    for i, entry in enumerate(poses):
        where = f"{path}: poses[{i}]"
        if not isinstance(entry, dict) or set(entry) != _POSE_KEYS:
            raise ValueError(f"{where} must have exactly the keys capture, translation, quaternion; got "
                             f"{sorted(entry) if isinstance(entry, dict) else entry!r}")
        capture = path.parent / str(entry["capture"])
        if not capture.exists():
            raise FileNotFoundError(f"{where}.capture: {capture}: no such file or folder")
        translation = _numbers(entry["translation"], 3, f"{where}.translation", "x, y, z")
        quaternion = _numbers(entry["quaternion"], 4, f"{where}.quaternion", "qx, qy, qz, qw")
        norm = float(np.linalg.norm(quaternion))
        if abs(norm - 1.0) > _UNIT_TOLERANCE:
            raise ValueError(f"{where}.quaternion must be 4 numbers [qx, qy, qz, qw] of unit norm; got "
                             f"{entry['quaternion']} (norm {norm:.6g})")
        captures.append(capture)
        flange.append(rigid(Rotation.from_quat(quaternion / norm).as_matrix(), translation * _UNITS[units]))
    return HandEyeViews(path=path, setup=setup, base_frame=frames["base_frame"], flange_frame=frames["flange_frame"],
                        captures=tuple(captures), flange_poses=tuple(flange))


def load_board_image(path) -> np.ndarray:
    """The board image of one capture: an image file, a capture folder's white reference, or a calibration pose
    folder's (``x/``, else ``y/``); (H, W) mono."""
    path = Path(path)
    if path.is_dir():
        folders = [path] if (path / "capture.yaml").is_file() else [path / axis for axis in ("x", "y")
                                                                     if (path / axis / "capture.yaml").is_file()]
        if not folders:
            raise ValueError(f"{path}: neither a dptpu-capture/1 folder nor a calibration pose folder (x/, y/)")
        for folder in folders:
            image = load_reference(read_capture(folder), "white")
            if image is not None:
                return image
        raise ValueError(f"{path}: the capture has no white reference (references: {{white: ...}}) to find the "
                         "board in")
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ValueError(f"{path}: not an image OpenCV can read (PNG, TIFF, ...)")
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    return image


def write_mount_file(path, result: HandEyeResult, views: HandEyeViews, *, camera_frame: str = "") -> Path:
    """Write the mount as a ROS 2 parameter file of the cloud node (module docstring); returns the path.

    ``mount_frame`` is the flange frame (eye-in-hand) or the base frame (eye-to-hand); ``mount_transform`` the
    camera optical frame's pose in it, ``[x, y, z, qx, qy, qz, qw]`` in metres. ``camera_frame`` (optional) is
    written as the cloud's ``frame_id``.
    """
    parent = views.flange_frame if result.setup == "eye-in-hand" else views.base_frame
    parameters: dict = {"mount_frame": parent,
                        "mount_transform": [round(v, 9) for v in pose_to_xyz_quaternion(result.mount[:3, :3],
                                                                                        result.mount[:3, 3])]}
    if camera_frame:
        parameters["frame_id"] = camera_frame
    header = (f"# dptpu calibrate hand-eye ({result.setup}, {len(result.view_rms_px)} views of {views.path.name}): "
              f"board corners reproject with RMS {result.rms_px:.3f} px after the joint refinement (started from "
              f"{result.initial_method}).\n# The camera optical frame's pose in {parent}; pass this file to the cloud "
              f"node (param: [{{from: {Path(path).name}}}]).\n")
    path = Path(path)
    path.write_text(header + yaml.safe_dump({"/**": {"ros__parameters": parameters}}, sort_keys=False,
                                           default_flow_style=None))
    return path


def _numbers(value, count: int, where: str, names: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != count or \
            not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise ValueError(f"{where} must be {count} numbers [{names}]; got {value!r}")
    out = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{where} must be {count} finite numbers [{names}]; got {value!r}")
    return out
