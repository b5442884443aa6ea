"""Writing a capture folder: arrays as PNG frames and a ``capture.yaml``, validated before it is written."""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from .model import (
    CAPTURE_FILE,
    CAPTURE_FORMAT,
    GROUND_TRUTH_KEYS,
    TOP_LEVEL_KEYS,
    Capture,
    GraycodeFrames,
    PatternLevels,
    PhaseFrames,
    PhaseSequence,
    format_number,
)
from .reading import parse_capture

__all__ = ["write_capture", "write_capture_yaml"]


def write_capture(
    folder,
    *,
    sequences: Sequence[PhaseFrames | GraycodeFrames],
    projector_size: tuple[int, int],
    fringe_axis: str = "x",
    phase_shift_sign: int = -1,
    pattern: PatternLevels | None = None,
    references: Mapping[str, np.ndarray] | None = None,
    calibration=None,
    ground_truth: Mapping[str, np.ndarray] | None = None,
    extras: Mapping[str, Any] | None = None,
    ground_truth_name: str = "ground_truth.npz",
) -> Capture:
    """Write frames as a ``dptpu-capture/1`` folder and return it as :func:`read_capture` reads it.

    Parameters
    ----------
    folder : path-like
        Created if absent; existing files of the same names are overwritten.
    sequences : list of PhaseFrames or GraycodeFrames
        Frames ``(N, H, W)`` of one dtype for the whole capture: ``uint8`` (bit depth 8) or ``uint16``
        (16). Files are named ``seq<i>_f<frequency>_s<n>.png`` (or ``_p<period>``), Gray code
        ``seq<i>_gray_b<bit>.png`` (+ ``_inv``, ``seq<i>_gray_complementary[_inv].png``).
    projector_size : (int, int)
        Projector ``(width, height)`` in pixels.
    fringe_axis, phase_shift_sign : str, int
        As in ``capture.yaml``.
    pattern : PatternLevels, optional
        Projected levels, written as ``pattern``.
    references : dict, optional
        ``{"white": (H, W), "black": (H, W)}`` frames, written as ``white.png``/``black.png``.
    calibration : path-like, optional
        A rig file, copied into the folder as ``calibration<suffix>``.
    ground_truth : dict, optional
        ``{"projector_x": (H, W) float, "valid": (H, W) bool}`` (more keys are kept), written as
        ``ground_truth_name`` (default ``ground_truth.npz``; the twin writes ``gt.npz``).
    extras : dict, optional
        More top-level keys for ``capture.yaml``.

    Returns
    -------
    Capture
    """
    if not sequences:
        raise ValueError("sequences must hold at least one PhaseFrames")
    stacks = []
    for i, frames in enumerate(sequences):
        if not isinstance(frames, (PhaseFrames, GraycodeFrames)):
            raise ValueError(f"sequences[{i}] must be PhaseFrames or GraycodeFrames; got {type(frames).__name__}")
        stacks.append(("images", frames.images))
        if isinstance(frames, GraycodeFrames):
            if frames.inverse is not None:
                stacks.append(("inverse", frames.inverse))
            for name in ("complementary", "complementary_inverse"):
                if getattr(frames, name) is not None:
                    stacks.append((name, np.asarray(getattr(frames, name))[None]))
    stacks.extend((name, np.asarray(image)[None]) for name, image in (references or {}).items())
    dtype, shape = _common_frame_format(stacks)
    bit_depth = 8 if dtype == np.uint8 else 16

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    document: dict[str, Any] = {
        "format": CAPTURE_FORMAT,
        "camera": {"size": [shape[1], shape[0]], "bit_depth": bit_depth},
        "projector": {"size": [int(v) for v in projector_size]},
        "fringe_axis": fringe_axis,
        "phase_shift_sign": phase_shift_sign,
    }
    if pattern is not None:
        document["pattern"] = {"offset": float(pattern.offset), "amplitude": float(pattern.amplitude)}
    document["sequences"] = [_write_frames(folder, i, frames) for i, frames in enumerate(sequences)]
    if references:
        document["references"] = {}
        for name, image in references.items():
            document["references"][name] = _write_png(folder, f"{name}.png", np.asarray(image))
    if calibration is not None:
        source = Path(calibration)
        if not source.is_file():
            raise FileNotFoundError(f"{source}: no such calibration file")
        target = folder / f"calibration{source.suffix or '.yaml'}"
        if source.resolve() != target.resolve():
            shutil.copyfile(source, target)
        document["calibration"] = target.name
    if ground_truth is not None:
        document["ground_truth"] = _write_ground_truth(folder, ground_truth, shape, ground_truth_name)
    for key, value in (extras or {}).items():
        if key in TOP_LEVEL_KEYS:
            raise ValueError(f"extras must not redefine the format key {key!r}")
        document[key] = value
    return _dump_document(document, folder)


def write_capture_yaml(capture: Capture, folder=None) -> Path:
    """Write the ``capture.yaml`` describing ``capture`` (its frames must already exist).

    Parameters
    ----------
    capture : Capture
    folder : path-like, optional
        Where to write ``capture.yaml`` (default ``capture.root``). Files inside this folder are written
        as relative names, others as absolute paths.

    Returns
    -------
    Path
        The written ``capture.yaml``; it is validated by reading it back first.
    """
    folder = Path(folder) if folder is not None else capture.root
    folder.mkdir(parents=True, exist_ok=True)
    base = folder.resolve()

    def name(path: Path) -> str:
        try:
            return Path(path).resolve().relative_to(base).as_posix()
        except ValueError:
            return str(Path(path).resolve())

    document: dict[str, Any] = {
        "format": CAPTURE_FORMAT,
        "camera": {"size": list(capture.camera_size), "bit_depth": capture.bit_depth},
        "projector": {"size": list(capture.projector_size)},
        "fringe_axis": capture.fringe_axis,
        "phase_shift_sign": capture.phase_shift_sign,
    }
    if capture.pattern is not None:
        document["pattern"] = {"offset": capture.pattern.offset, "amplitude": capture.pattern.amplitude}
    entries = []
    for sequence in capture.sequences:
        if isinstance(sequence, PhaseSequence):
            entry: dict[str, Any] = ({"frequency": sequence.frequency} if sequence.frequency is not None
                                     else {"period": sequence.period})
            entry["steps"] = sequence.steps
            entry["images"] = [name(p) for p in sequence.images]
            if sequence.phase_offset:
                entry["phase_offset"] = sequence.phase_offset
        else:
            entry = {"kind": "graycode", "bits": sequence.bits, "period": sequence.period,
                     "images": [name(p) for p in sequence.images]}
            if sequence.inverse is not None:
                entry["inverse"] = [name(p) for p in sequence.inverse]
            if sequence.complementary is not None:
                entry["complementary"] = name(sequence.complementary)
            if sequence.complementary_inverse is not None:
                entry["complementary_inverse"] = name(sequence.complementary_inverse)
        entry.update(sequence.extras)
        entries.append(entry)
    document["sequences"] = entries
    if capture.references:
        document["references"] = {k: name(v) for k, v in capture.references.items()}
    if capture.calibration is not None:
        document["calibration"] = name(capture.calibration)
    if capture.ground_truth is not None:
        document["ground_truth"] = name(capture.ground_truth)
    document.update(capture.extras)
    _dump_document(document, folder)
    return folder / CAPTURE_FILE


def _dump_document(document: dict, folder: Path) -> Capture:
    """Validate ``document`` as the capture of ``folder``, then write it as ``capture.yaml``."""
    path = folder / CAPTURE_FILE
    capture = parse_capture(document, folder.resolve(), str(path))
    path.write_text(yaml.safe_dump(_plain(document), sort_keys=False, default_flow_style=None, width=100))
    return capture


def _plain(value):
    """Tuples, numpy scalars and Paths as YAML-safe builtins."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value


def _common_frame_format(stacks) -> tuple[np.dtype, tuple[int, int]]:
    dtype: np.dtype | None = None
    shape: tuple[int, int] | None = None
    for name, stack in stacks:
        stack = np.asarray(stack)
        if stack.ndim != 3 or stack.shape[0] < 1:
            raise ValueError(f"{name} frames must have shape (N, H, W) (one frame: (H, W)); got {stack.shape}")
        if stack.dtype not in (np.uint8, np.uint16):
            raise ValueError(f"{name} frames must be uint8 or uint16 (the capture's bit depth); got {stack.dtype}")
        if dtype is None:
            dtype, shape = stack.dtype, (stack.shape[1], stack.shape[2])
        elif stack.dtype != dtype or stack.shape[1:] != shape:
            raise ValueError(f"all frames of a capture must share one dtype and size; got {name} "
                             f"{stack.dtype} {stack.shape[1:]} after {dtype} {shape}")
    if dtype is None or shape is None:
        raise ValueError("a capture needs at least one stack of frames")
    return dtype, shape


def _write_frames(folder: Path, index: int, frames: PhaseFrames | GraycodeFrames) -> dict:
    if isinstance(frames, PhaseFrames):
        if frames.frequency is not None and frames.period is None:
            key, value, tag = "frequency", float(frames.frequency), f"f{format_number(frames.frequency)}"
        elif frames.period is not None and frames.frequency is None:
            key, value, tag = "period", float(frames.period), f"p{format_number(frames.period)}"
        else:
            raise ValueError(f"sequences[{index}]: give exactly one of frequency and period")
        images = np.asarray(frames.images)
        entry: dict[str, Any] = {key: value, "steps": int(images.shape[0])}
        entry["images"] = [_write_png(folder, f"seq{index}_{tag}_s{n:02d}.png", image)
                           for n, image in enumerate(images)]
        if frames.phase_offset:
            entry["phase_offset"] = float(frames.phase_offset)
        return entry
    images = np.asarray(frames.images)
    entry = {"kind": "graycode", "bits": int(images.shape[0]), "period": float(frames.period)}
    entry["images"] = [_write_png(folder, f"seq{index}_gray_b{b}.png", image) for b, image in enumerate(images)]
    if frames.inverse is not None:
        entry["inverse"] = [_write_png(folder, f"seq{index}_gray_b{b}_inv.png", image)
                            for b, image in enumerate(np.asarray(frames.inverse))]
    if frames.complementary is not None:
        entry["complementary"] = _write_png(folder, f"seq{index}_gray_complementary.png",
                                            np.asarray(frames.complementary))
    if frames.complementary_inverse is not None:
        entry["complementary_inverse"] = _write_png(folder, f"seq{index}_gray_complementary_inv.png",
                                                    np.asarray(frames.complementary_inverse))
    return entry


def _write_png(folder: Path, name: str, image: np.ndarray) -> str:
    if not cv2.imwrite(str(folder / name), image):
        raise ValueError(f"could not write {folder / name}")
    return name


def _write_ground_truth(folder: Path, ground_truth: Mapping[str, np.ndarray], shape,
                        name: str = "ground_truth.npz") -> str:
    if not name.endswith(".npz") or "/" in name or "\\" in name:
        raise ValueError(f"ground_truth_name must be a file name ending in .npz; got {name!r}")
    missing = [k for k in GROUND_TRUTH_KEYS if k not in ground_truth]
    if missing:
        raise ValueError(f"ground_truth needs keys {list(GROUND_TRUTH_KEYS)}; missing {missing}")
    arrays = {k: np.asarray(v) for k, v in ground_truth.items()}
    for key in GROUND_TRUTH_KEYS:
        if arrays[key].shape != tuple(shape):
            raise ValueError(f"ground_truth {key} must have the frames' shape (H, W) = {tuple(shape)}; "
                             f"got {arrays[key].shape}")
    arrays["projector_x"] = arrays["projector_x"].astype(np.float32)
    arrays["valid"] = arrays["valid"].astype(bool)
    # allow_pickle: numpy's default, named so the type checker sees that no key of `arrays` can stand for it
    np.savez_compressed(folder / name, allow_pickle=True, **arrays)
    return name
