"""What a ``dptpu-capture/1`` folder holds: its names and keys, and the types :func:`read_capture` returns.

Convention: ``camera.size`` and ``projector.size`` are ``(width, height)`` in pixels, while image arrays are
``(H, W)`` and stacks ``(N, H, W)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

__all__ = [
    "CAPTURE_FORMAT",
    "CAPTURE_FILE",
    "FRINGE_AXES",
    "BIT_DEPTHS",
    "REFERENCE_NAMES",
    "TOP_LEVEL_KEYS",
    "PHASE_KEYS",
    "GRAYCODE_KEYS",
    "GROUND_TRUTH_KEYS",
    "PatternLevels",
    "PhaseSequence",
    "GraycodeSequence",
    "Capture",
    "GroundTruth",
    "PhaseFrames",
    "GraycodeFrames",
    "format_number",
]

#: The value of the ``format`` key.
CAPTURE_FORMAT = "dptpu-capture/1"
#: The description file inside a capture folder.
CAPTURE_FILE = "capture.yaml"

#: The values and the keys the format knows (other keys are kept as ``extras``).
FRINGE_AXES = ("x", "y")
BIT_DEPTHS = (8, 16)
REFERENCE_NAMES = ("white", "black")
TOP_LEVEL_KEYS = (
    "format", "camera", "projector", "fringe_axis", "phase_shift_sign", "pattern", "sequences",
    "references", "calibration", "ground_truth",
)
PHASE_KEYS = ("kind", "frequency", "period", "steps", "images", "phase_offset")
GRAYCODE_KEYS = ("kind", "bits", "period", "images", "inverse", "complementary", "complementary_inverse")
GROUND_TRUTH_KEYS = ("projector_x", "valid")


@dataclass(frozen=True)
class PatternLevels:
    """Projected level ``offset + amplitude*cos(.)`` as a fraction of the projector's full scale."""

    offset: float = 0.5
    amplitude: float = 0.45


@dataclass(frozen=True)
class PhaseSequence:
    """One ``N``-step phase-shifted fringe sequence of a capture.

    Attributes
    ----------
    steps : int
        Number of phase steps ``N >= 3``.
    images : tuple of Path
        ``N`` frame files, step order ``n = 0..N-1`` (absolute paths, resolved against the folder).
    frequency : float or None
        Fringe periods across the projector extent along the fringe axis (> 0), or None when the
        sequence was declared by ``period``.
    period : float or None
        Fringe period in projector pixels (> 0), or None when declared by ``frequency``.
    phase_offset : float
        Radians added to every image: ``I_n = A + B cos(phi + phase_offset + sign*2*pi*n/N)``.
    extras : dict
        Keys of the sequence entry this module does not know, kept as read.
    """

    steps: int
    images: tuple[Path, ...]
    frequency: float | None = None
    period: float | None = None
    phase_offset: float = 0.0
    extras: Mapping[str, Any] = field(default_factory=dict)
    kind: ClassVar[str] = "phase"

    def frequency_for(self, extent_px: float) -> float:
        """Frequency ``f`` (periods across the extent); derived as ``extent_px / period`` if needed.

        Parameters
        ----------
        extent_px : float
            Projector extent along the fringe axis, projector pixels (> 0).
        """
        if self.frequency is not None:
            return float(self.frequency)
        if self.period is None:
            raise ValueError("phase sequence declares neither frequency nor period")
        return float(extent_px) / float(self.period)

    @property
    def label(self) -> str:
        """How messages name the sequence, e.g. ``"frequency 96"`` or ``"period 42"``."""
        if self.frequency is not None:
            return f"frequency {format_number(self.frequency)}"
        return f"period {format_number(self.period)}"


@dataclass(frozen=True)
class GraycodeSequence:
    """A binary Gray-code sequence (MSB first) that indexes the periods of a phase sequence.

    Attributes
    ----------
    bits : int
        Number of code bits (>= 1); ``images`` holds one frame per bit, most significant first.
    period : float
        Projector pixels of one code step, equal to one period of the phase sequence it indexes.
    images : tuple of Path
        ``bits`` frame files.
    inverse : tuple of Path or None
        ``bits`` frames of the inverted patterns (per-pixel thresholds), or None.
    complementary : Path or None
        The extra half-period-shifted bit of complementary Gray code, or None.
    complementary_inverse : Path or None
        The inverse of the complementary bit; required when both ``inverse`` and ``complementary``
        are given.
    extras : dict
        Keys of the sequence entry this module does not know, kept as read.
    """

    bits: int
    period: float
    images: tuple[Path, ...]
    inverse: tuple[Path, ...] | None = None
    complementary: Path | None = None
    complementary_inverse: Path | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)
    kind: ClassVar[str] = "graycode"

    def frequency_for(self, extent_px: float) -> float:
        """Frequency of the phase sequence this code indexes, ``extent_px / period``."""
        return float(extent_px) / float(self.period)

    @property
    def label(self) -> str:
        """How messages name the sequence, e.g. ``"graycode, period 60"``."""
        return f"graycode, period {format_number(self.period)}"


@dataclass(frozen=True)
class Capture:
    """A validated ``dptpu-capture/1`` folder (paths only; frames are read on demand).

    Attributes
    ----------
    root : Path
        The capture folder (relative file names in ``capture.yaml`` are resolved against it).
    camera_size : (int, int)
        Camera ``(width, height)`` in pixels; every frame must be ``(height, width)``.
    bit_depth : int
        8 or 16: frames are ``uint8`` or ``uint16`` PNG, mono.
    projector_size : (int, int)
        Projector ``(width, height)`` in pixels.
    fringe_axis : {"x", "y"}
        ``x``: phase varies along projector columns (vertical stripes), extent = projector width.
    phase_shift_sign : {-1, +1}
        Image ``n`` is ``A + B cos(phi + phase_offset + sign*2*pi*n/N)``; -1 is the paper's Eq. (1).
    sequences : tuple of PhaseSequence or GraycodeSequence
        In file order.
    pattern : PatternLevels or None
        Projected levels, if declared.
    references : dict
        ``{"white": Path, "black": Path}`` (either may be absent).
    calibration : Path or None
        A rig file (``dptpu-rig/1``), if declared.
    ground_truth : Path or None
        An ``.npz`` with ``projector_x`` and ``valid`` (see :func:`load_ground_truth`), if declared.
    extras : dict
        Top-level keys this module does not know, kept as read.
    """

    root: Path
    camera_size: tuple[int, int]
    bit_depth: int
    projector_size: tuple[int, int]
    fringe_axis: str
    phase_shift_sign: int
    sequences: tuple[PhaseSequence | GraycodeSequence, ...]
    pattern: PatternLevels | None = None
    references: Mapping[str, Path] = field(default_factory=dict)
    calibration: Path | None = None
    ground_truth: Path | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)

    @property
    def fringe_extent_px(self) -> int:
        """Projector extent ``W_p`` along the fringe axis: width for ``x``, height for ``y``."""
        width, height = self.projector_size
        return width if self.fringe_axis == "x" else height

    @property
    def image_shape(self) -> tuple[int, int]:
        """``(H, W)`` of every frame (``camera_size`` is ``(width, height)``)."""
        width, height = self.camera_size
        return height, width

    @property
    def phase_sequences(self) -> tuple[PhaseSequence, ...]:
        """The phase-shifted sequences, in file order."""
        return tuple(s for s in self.sequences if isinstance(s, PhaseSequence))

    @property
    def graycode_sequences(self) -> tuple[GraycodeSequence, ...]:
        """The Gray-code sequences, in file order."""
        return tuple(s for s in self.sequences if isinstance(s, GraycodeSequence))

    def frequency_of(self, sequence: PhaseSequence | GraycodeSequence) -> float:
        """Frequency ``f`` of a sequence, derived from its period and ``fringe_extent_px`` if needed."""
        return sequence.frequency_for(self.fringe_extent_px)


@dataclass(frozen=True, eq=False)  # holds arrays: compare fields explicitly
class GroundTruth:
    """Ground truth of a (synthetic) capture.

    Attributes
    ----------
    projector_x : ndarray (H, W) float32
        Projector coordinate along the fringe axis seen by each camera pixel, projector pixels
        (0-based, pixel centres at integers); NaN where invalid.
    valid : ndarray (H, W) bool
        Pixels where ``projector_x`` holds.
    """

    projector_x: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True, eq=False)  # holds arrays: compare fields explicitly
class PhaseFrames:
    """A phase sequence to write with :func:`write_capture`: ``images (N, H, W)`` uint8 or uint16."""

    images: np.ndarray
    frequency: float | None = None
    period: float | None = None
    phase_offset: float = 0.0


@dataclass(frozen=True, eq=False)  # holds arrays: compare fields explicitly
class GraycodeFrames:
    """A Gray-code sequence to write with :func:`write_capture`.

    ``images (bits, H, W)``; optional ``inverse (bits, H, W)``, ``complementary (H, W)`` and
    ``complementary_inverse (H, W)`` (required when both ``inverse`` and ``complementary`` are given).
    """

    images: np.ndarray
    period: float
    inverse: np.ndarray | None = None
    complementary: np.ndarray | None = None
    complementary_inverse: np.ndarray | None = None


def format_number(value) -> str:
    """``96.0 -> "96"``, ``10.9 -> "10.9"``."""
    value = float(value)
    return str(int(value)) if value.is_integer() else repr(value)
