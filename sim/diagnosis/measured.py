"""The measured data of a diagnosis: raw frames (a ``dptpu-capture/1`` folder) or a phase file.

- A capture folder: every phase sequence's frames (float DN), decoded to an absolute phase of the highest
  frequency (MF when a 1-period sequence is present, else heterodyne), with the pattern levels the capture
  declares (``pattern: {offset, amplitude}``; default 0.5, 0.45).
- An ``.npz`` with ``absolute_phase`` (H, W, NaN invalid), ``frequency``, ``fringe_axis``, ``projector_size``.
- A ``.mat`` phase file of ``dptpu-sphere`` (``phase3`` or ``phase``; invalid where ``|phase| < 10``, the
  paper's rule) with ``frequency`` given (``--frequency 96``); projector 912x1140, fringe axis x.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dptpu.fpp.capture import PatternLevels, load_sequence_images, read_capture
from dptpu.fpp.mat_file import read_mat
from dptpu.fpp.reconstruct import unwrap_capture
from dptpu.sim.image_formation import SequenceSpec

__all__ = ["Measured", "load_measured"]

#: The paper's validity rule for its phase files (``|phase| >= 10`` rad).
MAT_MIN_PHASE = 10.0
MAT_PROJECTOR_SIZE = (912, 1140)


@dataclass
class Measured:
    """Measured data. ``frames``: list of (N, H, W) float64 DN per phase sequence (empty for a phase file),
    ``sequences`` their :class:`SequenceSpec`; ``absolute_phase`` (H, W) of ``frequency``, NaN invalid;
    ``valid`` (H, W) bool."""

    source: Path
    absolute_phase: np.ndarray
    frequency: float
    fringe_axis: str
    projector_size: tuple
    frames: list = field(default_factory=list)
    sequences: list = field(default_factory=list)
    bit_depth: int = 8
    pattern: PatternLevels = PatternLevels()
    calibration: Path | None = None

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.absolute_phase)

    @property
    def extent(self) -> int:
        return self.projector_size[0] if self.fringe_axis == "x" else self.projector_size[1]

    @property
    def projector_x(self) -> np.ndarray:
        """Measured projector coordinate along the fringe axis (H, W), projector px, NaN invalid."""
        return self.absolute_phase * self.extent / (2.0 * np.pi * self.frequency)

    @property
    def full_scale(self) -> float:
        return float(2 ** self.bit_depth - 1)

    @property
    def has_frames(self) -> bool:
        return bool(self.frames)


def load_measured(path, *, frequency: float | None = None, decode: bool = True) -> Measured:
    """Read a capture folder, an ``.npz`` phase file or a ``.mat`` phase file (module docstring).

    ``decode=False`` skips the temporal unwrapping of a capture (self-reference needs only the frames).
    """
    path = Path(path)
    if path.is_dir() or path.name == "capture.yaml":
        return _from_capture(path if path.is_dir() else path.parent, decode=decode)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such capture folder or phase file")
    if path.suffix == ".npz":
        return _from_npz(path)
    if path.suffix == ".mat":
        return _from_mat(path, frequency)
    raise ValueError(f"{path}: --measured must be a capture folder, an .npz phase file or a .mat phase file")


def _from_capture(folder: Path, *, decode: bool) -> Measured:
    capture = read_capture(folder)
    if capture.graycode_sequences:
        raise ValueError(f"{folder}: the diagnosis reads phase sequences only; this capture holds Gray code")
    frames, sequences = [], []
    for s in capture.phase_sequences:
        frames.append(load_sequence_images(capture, s).astype(np.float64))
        sequences.append(SequenceSpec(capture.frequency_of(s), s.steps, axis=capture.fringe_axis,
                                      shift_sign=capture.phase_shift_sign, phase_offset=s.phase_offset))
    height, width = capture.image_shape
    phase = np.full((height, width), np.nan)
    high = max(s.frequency for s in sequences)
    if decode:
        frequencies = [s.frequency for s in sequences]
        method = "mf" if len(frequencies) >= 2 and any(abs(f - 1.0) < 1e-9 for f in frequencies) else "heterodyne"
        if len(frequencies) < 2:
            raise ValueError(f"{folder}: decoding needs two or more phase sequences (e.g. 96x12 and 1x12); "
                             "use --self-reference for a single sequence")
        high_low = (high, 1.0) if method == "mf" else (None, None)
        # saturated pixels are kept (saturation is one of the effects diagnosed): level above full scale
        result = unwrap_capture(capture, method=method, high=high_low[0], low=high_low[1],
                                saturation_level=2.0 ** capture.bit_depth)
        phase = np.where(result.valid, result.absolute_phase, np.nan)
        high = result.frequency
    return Measured(source=folder, absolute_phase=phase, frequency=float(high), fringe_axis=capture.fringe_axis,
                    projector_size=tuple(capture.projector_size), frames=frames, sequences=sequences,
                    bit_depth=capture.bit_depth, pattern=capture.pattern or PatternLevels(),
                    calibration=capture.calibration)


def _from_npz(path: Path) -> Measured:
    data = np.load(path, allow_pickle=False)
    missing = [k for k in ("absolute_phase", "frequency", "fringe_axis", "projector_size") if k not in data]
    if missing:
        raise ValueError(f"{path}: missing key(s) {', '.join(missing)}; a phase file holds absolute_phase (HxW, "
                         "NaN invalid), frequency, fringe_axis and projector_size")
    phase = np.asarray(data["absolute_phase"], dtype=np.float64)
    if phase.ndim != 2:
        raise ValueError(f"{path}: absolute_phase must have shape (H, W); got {phase.shape}")
    axis = str(data["fringe_axis"])
    if axis not in ("x", "y"):
        raise ValueError(f"{path}: fringe_axis must be 'x' or 'y'; got {axis!r}")
    size = tuple(int(v) for v in np.ravel(data["projector_size"]))
    if len(size) != 2:
        raise ValueError(f"{path}: projector_size must be [width, height]; got {size}")
    if "valid" in data:
        phase = np.where(np.asarray(data["valid"], bool), phase, np.nan)
    return Measured(source=path, absolute_phase=phase, frequency=float(data["frequency"]), fringe_axis=axis,
                    projector_size=size)


def _from_mat(path: Path, frequency) -> Measured:
    if frequency is None:
        raise ValueError(f"{path}: a .mat phase file needs --frequency (96 for the dptpu-sphere data)")
    data = read_mat(path, what="phase file")
    arrays = {k: v for k, v in data.items() if not k.startswith("__") and getattr(v, "ndim", 0) == 2
              and min(v.shape) > 8}
    if not arrays:
        raise ValueError(f"{path}: no 2-D phase array found (expected e.g. 'phase3' or 'phase')")
    values = np.asarray(arrays.get("phase3", arrays.get("phase", next(iter(arrays.values())))), dtype=np.float64)
    with np.errstate(invalid="ignore"):
        phase = np.where(np.abs(values) >= MAT_MIN_PHASE, values, np.nan)
    return Measured(source=path, absolute_phase=phase, frequency=float(frequency), fringe_axis="x",
                    projector_size=MAT_PROJECTOR_SIZE)
