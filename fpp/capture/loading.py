"""Loading a capture's frames, reference frames and ground truth, each checked against ``camera``."""

from __future__ import annotations

import os
import zipfile
from collections.abc import Sequence

import cv2
import numpy as np

from .model import (
    CAPTURE_FILE,
    GROUND_TRUTH_KEYS,
    REFERENCE_NAMES,
    Capture,
    GraycodeSequence,
    GroundTruth,
    PhaseSequence,
)
from .reading import resolve_path

__all__ = ["load_image", "load_images", "load_sequence_images", "load_reference", "load_ground_truth"]


def load_image(capture: Capture, path) -> np.ndarray:
    """Read one mono frame of the capture and check it against ``camera``.

    Parameters
    ----------
    capture : Capture
        Gives the expected size and bit depth.
    path : path-like
        The frame (relative paths are resolved against ``capture.root``). Any file OpenCV reads is
        accepted; PNG is the format's choice.

    Returns
    -------
    ndarray (H, W) uint8 or uint16
        Digital numbers as stored (``uint8`` for ``bit_depth`` 8, ``uint16`` for 16).

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        The file is not a readable image, is colour (3 or 4 channels: captures are mono; convert with
        e.g. ``cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)`` before writing), its size differs from
        ``camera.size``, or its sample type does not match ``camera.bit_depth``.
    """
    path = resolve_path(capture.root, str(path))
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such image file")
    if not os.access(path, os.R_OK):  # OpenCV returns None for it as for a broken file: say which it is
        raise ValueError(f"{path}: cannot read the image (permission denied)")
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ValueError(f"{path.name}: not an image OpenCV can read ({path})")
    if image.ndim == 3:
        if image.shape[2] == 1:
            image = image[:, :, 0]
        else:
            raise ValueError(f"{path.name} is a colour image ({image.shape[2]} channels); captures are mono: "
                             f"convert it to grey before writing the capture")
    height, width = image.shape
    if (width, height) != tuple(capture.camera_size):
        raise ValueError(f"{path.name} is {width}x{height}, camera.size is "
                         f"{capture.camera_size[0]}x{capture.camera_size[1]}")
    expected = np.uint8 if capture.bit_depth == 8 else np.uint16
    if image.dtype != expected:
        actual = {np.dtype(np.uint8): "an 8-bit", np.dtype(np.uint16): "a 16-bit"}.get(image.dtype, f"a {image.dtype}")
        raise ValueError(f"{path.name} is {actual} image, camera.bit_depth is {capture.bit_depth} "
                         f"(frames must be {np.dtype(expected).name})")
    return image


def load_images(capture: Capture, paths: Sequence) -> np.ndarray:
    """Read several frames with :func:`load_image` into a stack ``(N, H, W)`` uint8 or uint16."""
    return np.stack([load_image(capture, p) for p in paths])


def load_sequence_images(capture: Capture, sequence: PhaseSequence | GraycodeSequence) -> np.ndarray:
    """The frames of one sequence, ``(N, H, W)`` (phase: ``N = steps``; Gray code: ``N = bits``).

    Frames are in step (or bit, MSB first) order and checked as in :func:`load_image`. The inverse and
    complementary frames of a Gray-code sequence are read with :func:`load_images`/:func:`load_image`.
    """
    return load_images(capture, sequence.images)


def load_reference(capture: Capture, name: str) -> np.ndarray | None:
    """The ``white`` or ``black`` reference frame ``(H, W)``, or None when the capture has none."""
    if name not in REFERENCE_NAMES:
        raise ValueError(f"reference name must be 'white' or 'black'; got {name!r}")
    path = capture.references.get(name)
    return None if path is None else load_image(capture, path)


def load_ground_truth(capture: Capture) -> GroundTruth:
    """Read the capture's ground-truth ``.npz`` (keys ``projector_x`` and ``valid``, both ``(H, W)``).

    Raises
    ------
    ValueError
        The capture declares no ground truth, a key is missing, or an array's shape is not the
        camera's ``(H, W)``.
    """
    if capture.ground_truth is None:
        raise ValueError(f"{capture.root / CAPTURE_FILE}: the capture declares no ground_truth")
    path = capture.ground_truth
    if not zipfile.is_zipfile(path):  # np.load would take other bytes for a pickle, or a single .npy array
        raise ValueError(f"{path}: not a ground-truth .npz (a zip archive of .npy arrays, np.savez)")
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in GROUND_TRUTH_KEYS if k not in data.files]
            if missing:
                raise ValueError(f"{path.name}: missing key(s) {missing}; a ground-truth npz holds "
                                 f"projector_x (H, W) float32 and valid (H, W) bool; got {sorted(data.files)}")
            projector_x = np.asarray(data["projector_x"], dtype=np.float32)
            valid = np.asarray(data["valid"])
    except (OSError, EOFError, zipfile.BadZipFile) as exc:  # not a zip, cut short, a folder, unreadable
        raise ValueError(f"{path}: not a readable ground-truth .npz ({str(exc) or type(exc).__name__})") from None
    except ValueError as exc:
        if str(exc).startswith(path.name):
            raise
        raise ValueError(f"{path}: not a readable ground-truth .npz ({exc})") from None
    for name, array in (("projector_x", projector_x), ("valid", valid)):
        if array.shape != capture.image_shape:
            raise ValueError(f"{path.name}: {name} must have the camera's shape (H, W) = "
                             f"{capture.image_shape}; got {array.shape}")
    if valid.dtype != np.bool_:
        raise ValueError(f"{path.name}: valid must be bool; got {valid.dtype}")
    return GroundTruth(projector_x=projector_x, valid=valid)
