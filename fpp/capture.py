"""Capture folders, format ``dptpu-capture/1``: read, validate, load frames, write.

A capture folder holds the camera frames of one scan and a ``capture.yaml`` that says what they are
(docs/capture-format.md is the full specification)::

    format: dptpu-capture/1
    camera: {size: [640, 480], bit_depth: 8}     # width, height; 8 or 16 (PNG, mono)
    projector: {size: [912, 1140]}                # width, height
    fringe_axis: x                                # phase varies along projector x (vertical stripes)
    phase_shift_sign: -1                          # image n is A + B cos(phi + sign*2*pi*n/N)
    sequences:
      - {frequency: 96, steps: 12, images: [f96_s00.png, ...]}
      - {kind: graycode, bits: 5, period: 60, images: [g0.png, ...]}

Public API:

- :func:`read_capture` -- parse and validate a folder into a :class:`Capture` (no pixels are read);
- :func:`load_sequence_images`, :func:`load_image`, :func:`load_reference`, :func:`load_ground_truth`
  -- read frames, checking size and bit depth against ``camera``;
- :func:`write_capture` -- write arrays as a capture folder (PNG frames + ``capture.yaml``);
- :func:`write_capture_yaml` -- write the ``capture.yaml`` of a :class:`Capture` whose frames exist.

Validation is strict: a missing required key, a wrong type, an impossible value or an image count that
does not match ``steps`` raises ``ValueError`` naming the file and the key; listed files that do not
exist raise ``FileNotFoundError`` naming every one of them. Extra (unknown) keys are allowed at the top
level and in sequences; they are kept in ``extras``.

Convention: ``camera.size`` and ``projector.size`` are ``(width, height)`` in pixels, while image
arrays are ``(H, W)`` and stacks ``(N, H, W)``. ``phi = 2*pi*f*x_p/W_p`` with ``W_p`` the projector
extent along ``fringe_axis`` (width for ``x``, height for ``y``); a ``period`` ``T`` in projector
pixels is the frequency ``f = W_p / T``.
"""
from __future__ import annotations

import numbers
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Mapping, Sequence

import cv2
import numpy as np
import yaml

__all__ = [
    "CAPTURE_FORMAT",
    "CAPTURE_FILE",
    "PatternLevels",
    "PhaseSequence",
    "GraycodeSequence",
    "Capture",
    "GroundTruth",
    "PhaseFrames",
    "GraycodeFrames",
    "read_capture",
    "load_image",
    "load_images",
    "load_sequence_images",
    "load_reference",
    "load_ground_truth",
    "write_capture",
    "write_capture_yaml",
]

#: The value of the ``format`` key.
CAPTURE_FORMAT = "dptpu-capture/1"
#: The description file inside a capture folder.
CAPTURE_FILE = "capture.yaml"

_FRINGE_AXES = ("x", "y")
_BIT_DEPTHS = (8, 16)
_REFERENCE_NAMES = ("white", "black")
_TOP_LEVEL_KEYS = (
    "format", "camera", "projector", "fringe_axis", "phase_shift_sign", "pattern", "sequences",
    "references", "calibration", "ground_truth",
)
_PHASE_KEYS = ("kind", "frequency", "period", "steps", "images", "phase_offset")
_GRAYCODE_KEYS = ("kind", "bits", "period", "images", "inverse", "complementary", "complementary_inverse")
_GROUND_TRUTH_KEYS = ("projector_x", "valid")


# --------------------------------------------------------------------------------------------------
# Data model
# --------------------------------------------------------------------------------------------------

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
        return float(extent_px) / float(self.period)

    @property
    def label(self) -> str:
        """How messages name the sequence, e.g. ``"frequency 96"`` or ``"period 42"``."""
        if self.frequency is not None:
            return f"frequency {_format_number(self.frequency)}"
        return f"period {_format_number(self.period)}"


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
        return f"graycode, period {_format_number(self.period)}"


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


# --------------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------------

def read_capture(path) -> Capture:
    """Read and validate a ``dptpu-capture/1`` folder.

    Parameters
    ----------
    path : path-like
        The capture folder, or its ``capture.yaml``.

    Returns
    -------
    Capture
        With every listed file resolved to an absolute path (no pixels are read).

    Raises
    ------
    FileNotFoundError
        The folder has no ``capture.yaml``, or files it lists do not exist (all are named).
    ValueError
        A required key is missing (``"capture.yaml: missing key 'projector.size'"``), a value has the
        wrong type or range, ``format`` is not ``dptpu-capture/1``, a phase sequence gives both or
        neither of ``frequency`` and ``period``, or an image list does not match ``steps``/``bits``.
    """
    yaml_path = Path(path)
    if not yaml_path.exists():
        raise FileNotFoundError(f"{yaml_path}: no such capture folder or {CAPTURE_FILE}")
    if yaml_path.is_dir():
        yaml_path = yaml_path / CAPTURE_FILE
    if not yaml_path.is_file():
        raise FileNotFoundError(f"{yaml_path}: no such file (a capture folder needs a {CAPTURE_FILE})")
    try:
        document = yaml.safe_load(yaml_path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{yaml_path}: not valid YAML ({exc})") from None
    return _parse_capture(document, yaml_path.parent.resolve(), str(yaml_path))


def _parse_capture(document, root: Path, source: str) -> Capture:
    """Validate a parsed ``capture.yaml`` document; ``source`` names the file in messages."""
    spec = _Spec(source)
    if not isinstance(document, dict):
        spec.fail(f"must be a mapping of keys (format: {CAPTURE_FORMAT}, camera, ...); "
                  f"got {type(document).__name__}")
    fmt = spec.require(document, "format")
    if fmt != CAPTURE_FORMAT:
        spec.fail(f"format must be '{CAPTURE_FORMAT}'; got {fmt!r}")

    camera = spec.mapping(spec.require(document, "camera"), "camera")
    camera_size = spec.size(spec.require(camera, "size", "camera.size"), "camera.size")
    bit_depth = spec.require(camera, "bit_depth", "camera.bit_depth")
    if isinstance(bit_depth, bool) or bit_depth not in _BIT_DEPTHS:
        spec.fail(f"camera.bit_depth must be 8 or 16; got {bit_depth!r}")
    projector = spec.mapping(spec.require(document, "projector"), "projector")
    projector_size = spec.size(spec.require(projector, "size", "projector.size"), "projector.size")

    fringe_axis = spec.require(document, "fringe_axis")
    if fringe_axis not in _FRINGE_AXES:
        spec.fail(f"fringe_axis must be 'x' (vertical stripes) or 'y'; got {fringe_axis!r}")
    sign = spec.require(document, "phase_shift_sign")
    if isinstance(sign, bool) or sign not in (-1, 1):
        spec.fail(f"phase_shift_sign must be -1 (the paper's Eq. 1) or +1; got {sign!r}")
    extent = projector_size[0] if fringe_axis == "x" else projector_size[1]

    pattern = None
    if document.get("pattern") is not None:
        pattern = _parse_pattern(spec, document["pattern"])

    raw_sequences = spec.require(document, "sequences")
    if not isinstance(raw_sequences, list) or not raw_sequences:
        spec.fail(f"sequences must be a non-empty list; got {raw_sequences!r}")
    sequences = tuple(_parse_sequence(spec, raw, i, root, extent) for i, raw in enumerate(raw_sequences))
    if not any(isinstance(s, PhaseSequence) for s in sequences):
        spec.fail("sequences must hold at least one phase sequence (kind: phase)")

    references = {}
    if document.get("references") is not None:
        raw_refs = spec.mapping(document["references"], "references")
        for name, value in raw_refs.items():
            if name not in _REFERENCE_NAMES:
                spec.fail(f"references may hold 'white' and 'black'; got unknown key {name!r}")
            references[name] = _resolve(root, spec.file_name(value, f"references.{name}"))
    calibration = ground_truth = None
    if document.get("calibration") is not None:
        calibration = _resolve(root, spec.file_name(document["calibration"], "calibration"))
    if document.get("ground_truth") is not None:
        ground_truth = _resolve(root, spec.file_name(document["ground_truth"], "ground_truth"))

    capture = Capture(
        root=root, camera_size=camera_size, bit_depth=int(bit_depth), projector_size=projector_size,
        fringe_axis=fringe_axis, phase_shift_sign=int(sign), sequences=sequences, pattern=pattern,
        references=references, calibration=calibration, ground_truth=ground_truth,
        extras={k: v for k, v in document.items() if k not in _TOP_LEVEL_KEYS},
    )
    missing = [p for p in _listed_files(capture) if not p.is_file()]
    if missing:
        names = ", ".join(_display(root, p) for p in missing)
        raise FileNotFoundError(f"{source}: {len(missing)} listed file(s) do not exist: {names} "
                                f"(relative names are looked up in {root})")
    return capture


def _parse_pattern(spec: "_Spec", raw) -> PatternLevels:
    raw = spec.mapping(raw, "pattern")
    offset = spec.number(spec.require(raw, "offset", "pattern.offset"), "pattern.offset")
    amplitude = spec.number(spec.require(raw, "amplitude", "pattern.amplitude"), "pattern.amplitude")
    if amplitude <= 0 or offset - amplitude < 0 or offset + amplitude > 1:
        spec.fail(f"pattern offset +- amplitude must stay within [0, 1] of full scale with amplitude > 0; "
                  f"got offset={offset}, amplitude={amplitude}")
    return PatternLevels(offset=offset, amplitude=amplitude)


def _parse_sequence(spec: "_Spec", raw, index: int, root: Path, extent: int):
    where = f"sequences[{index}]"
    raw = spec.mapping(raw, where)
    kind = raw.get("kind", "phase")
    if kind == "phase":
        return _parse_phase_sequence(spec, raw, index, root)
    if kind == "graycode":
        return _parse_graycode_sequence(spec, raw, index, root, extent)
    spec.fail(f"{where}.kind must be 'phase' (the default) or 'graycode'; got {kind!r}")


def _parse_phase_sequence(spec: "_Spec", raw: dict, index: int, root: Path) -> PhaseSequence:
    where = f"sequences[{index}]"
    has_frequency, has_period = raw.get("frequency") is not None, raw.get("period") is not None
    if has_frequency == has_period:
        spec.fail(f"{where}: give exactly one of 'frequency' and 'period'; got "
                  f"{'both' if has_frequency else 'neither'}")
    frequency = period = None
    if has_frequency:
        frequency = spec.positive(raw["frequency"], f"{where}.frequency")
    else:
        period = spec.positive(raw["period"], f"{where}.period")
    steps = spec.integer(spec.require(raw, "steps", f"{where}.steps"), f"{where}.steps", minimum=3)
    declared = f"frequency {_format_number(frequency)}" if has_frequency else f"period {_format_number(period)}"
    label = f"sequence {index} ({declared})"
    images = spec.file_list(spec.require(raw, "images", f"{where}.images"), f"{where}.images")
    if len(images) != steps:
        spec.fail(f"{label}: {len(images)} images listed but steps is {steps}")
    phase_offset = raw.get("phase_offset")
    phase_offset = 0.0 if phase_offset is None else spec.number(phase_offset, f"{where}.phase_offset")
    return PhaseSequence(
        steps=steps, images=tuple(_resolve(root, name) for name in images), frequency=frequency,
        period=period, phase_offset=phase_offset,
        extras={k: v for k, v in raw.items() if k not in _PHASE_KEYS},
    )


def _parse_graycode_sequence(spec: "_Spec", raw: dict, index: int, root: Path, extent: int) -> GraycodeSequence:
    where = f"sequences[{index}]"
    bits = spec.integer(spec.require(raw, "bits", f"{where}.bits"), f"{where}.bits", minimum=1)
    period = spec.positive(spec.require(raw, "period", f"{where}.period"), f"{where}.period")
    label = f"sequence {index} (graycode, period {_format_number(period)})"
    if 2**bits * period < extent:
        spec.fail(f"{label}: {bits} bits cover 2**{bits} * {_format_number(period)} = "
                  f"{_format_number(2**bits * period)} projector pixels, less than the extent {extent} "
                  f"along the fringe axis")
    images = spec.file_list(spec.require(raw, "images", f"{where}.images"), f"{where}.images")
    if len(images) != bits:
        spec.fail(f"{label}: {len(images)} images listed but bits is {bits}")
    inverse = None
    if raw.get("inverse") is not None:
        inverse = spec.file_list(raw["inverse"], f"{where}.inverse")
        if len(inverse) != bits:
            spec.fail(f"{label}: {len(inverse)} inverse images listed but bits is {bits}")
        inverse = tuple(_resolve(root, name) for name in inverse)
    complementary = complementary_inverse = None
    if raw.get("complementary") is not None:
        complementary = _resolve(root, spec.file_name(raw["complementary"], f"{where}.complementary"))
    if raw.get("complementary_inverse") is not None:
        if complementary is None or inverse is None:
            spec.fail(f"{label}: complementary_inverse needs both complementary and inverse")
        complementary_inverse = _resolve(
            root, spec.file_name(raw["complementary_inverse"], f"{where}.complementary_inverse"))
    if inverse is not None and complementary is not None and complementary_inverse is None:
        spec.fail(f"{label}: missing key '{where}.complementary_inverse' (required when both inverse "
                  f"and complementary are given: the complementary bit needs its own inverse)")
    return GraycodeSequence(
        bits=bits, period=period, images=tuple(_resolve(root, name) for name in images), inverse=inverse,
        complementary=complementary, complementary_inverse=complementary_inverse,
        extras={k: v for k, v in raw.items() if k not in _GRAYCODE_KEYS},
    )


class _Spec:
    """Checks on a parsed YAML document whose failures name the file and the key."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, message: str):
        raise ValueError(f"{self.source}: {message}")

    def require(self, mapping: dict, key: str, dotted: str | None = None):
        if key not in mapping or mapping[key] is None:
            self.fail(f"missing key '{dotted or key}'")
        return mapping[key]

    def mapping(self, value, key: str) -> dict:
        if not isinstance(value, dict):
            self.fail(f"{key} must be a mapping; got {value!r}")
        return value

    def number(self, value, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value):
            self.fail(f"{key} must be a finite number; got {value!r}")
        return float(value)

    def positive(self, value, key: str) -> float:
        value = self.number(value, key)
        if value <= 0:
            self.fail(f"{key} must be > 0; got {_format_number(value)}")
        return value

    def integer(self, value, key: str, *, minimum: int) -> int:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
            self.fail(f"{key} must be an integer >= {minimum}; got {value!r}")
        return int(value)

    def size(self, value, key: str) -> tuple[int, int]:
        if (not isinstance(value, (list, tuple)) or len(value) != 2
                or any(isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 1 for v in value)):
            self.fail(f"{key} must be [width, height] in pixels (two positive integers); got {value!r}")
        return int(value[0]), int(value[1])

    def file_name(self, value, key: str) -> str:
        if not isinstance(value, str) or not value.strip():
            self.fail(f"{key} must be a file name (relative to the capture folder, or absolute); got {value!r}")
        return value

    def file_list(self, value, key: str) -> list[str]:
        if not isinstance(value, list):
            self.fail(f"{key} must be a list of file names; got {value!r}")
        return [self.file_name(v, f"{key}[{i}]") for i, v in enumerate(value)]


def _resolve(root: Path, name: str) -> Path:
    """``root / name``; an absolute ``name`` stays as it is."""
    return root / Path(name).expanduser()


def _display(root: Path, path: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def _listed_files(capture: Capture) -> list[Path]:
    files = []
    for sequence in capture.sequences:
        files.extend(sequence.images)
        if isinstance(sequence, GraycodeSequence):
            files.extend(sequence.inverse or ())
            files.extend(p for p in (sequence.complementary, sequence.complementary_inverse) if p is not None)
    files.extend(capture.references.values())
    files.extend(p for p in (capture.calibration, capture.ground_truth) if p is not None)
    return files


def _format_number(value) -> str:
    """``96.0 -> "96"``, ``10.9 -> "10.9"``."""
    value = float(value)
    return str(int(value)) if value.is_integer() else repr(value)


# --------------------------------------------------------------------------------------------------
# Loading frames
# --------------------------------------------------------------------------------------------------

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
    path = _resolve(capture.root, str(path))
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such image file")
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
    if name not in _REFERENCE_NAMES:
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
    with np.load(path) as data:
        missing = [k for k in _GROUND_TRUTH_KEYS if k not in data.files]
        if missing:
            raise ValueError(f"{path.name}: missing key(s) {missing}; a ground-truth npz holds "
                             f"projector_x (H, W) float32 and valid (H, W) bool; got {sorted(data.files)}")
        projector_x = np.asarray(data["projector_x"], dtype=np.float32)
        valid = np.asarray(data["valid"])
    for name, array in (("projector_x", projector_x), ("valid", valid)):
        if array.shape != capture.image_shape:
            raise ValueError(f"{path.name}: {name} must have the camera's shape (H, W) = "
                             f"{capture.image_shape}; got {array.shape}")
    if valid.dtype != np.bool_:
        raise ValueError(f"{path.name}: valid must be bool; got {valid.dtype}")
    return GroundTruth(projector_x=projector_x, valid=valid)


# --------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------

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
        if key in _TOP_LEVEL_KEYS:
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
    capture = _parse_capture(document, folder.resolve(), str(path))
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
    dtype = shape = None
    for name, stack in stacks:
        stack = np.asarray(stack)
        if stack.ndim != 3 or stack.shape[0] < 1:
            raise ValueError(f"{name} frames must have shape (N, H, W) (one frame: (H, W)); got {stack.shape}")
        if stack.dtype not in (np.uint8, np.uint16):
            raise ValueError(f"{name} frames must be uint8 or uint16 (the capture's bit depth); got {stack.dtype}")
        if dtype is None:
            dtype, shape = stack.dtype, stack.shape[1:]
        elif stack.dtype != dtype or stack.shape[1:] != shape:
            raise ValueError(f"all frames of a capture must share one dtype and size; got {name} "
                             f"{stack.dtype} {stack.shape[1:]} after {dtype} {shape}")
    return dtype, shape


def _write_frames(folder: Path, index: int, frames: PhaseFrames | GraycodeFrames) -> dict:
    if isinstance(frames, PhaseFrames):
        if (frames.frequency is None) == (frames.period is None):
            raise ValueError(f"sequences[{index}]: give exactly one of frequency and period")
        if frames.frequency is not None:
            key, value, tag = "frequency", float(frames.frequency), f"f{_format_number(frames.frequency)}"
        else:
            key, value, tag = "period", float(frames.period), f"p{_format_number(frames.period)}"
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
    missing = [k for k in _GROUND_TRUTH_KEYS if k not in ground_truth]
    if missing:
        raise ValueError(f"ground_truth needs keys {list(_GROUND_TRUTH_KEYS)}; missing {missing}")
    arrays = {k: np.asarray(v) for k, v in ground_truth.items()}
    for key in _GROUND_TRUTH_KEYS:
        if arrays[key].shape != tuple(shape):
            raise ValueError(f"ground_truth {key} must have the frames' shape (H, W) = {tuple(shape)}; "
                             f"got {arrays[key].shape}")
    arrays["projector_x"] = arrays["projector_x"].astype(np.float32)
    arrays["valid"] = arrays["valid"].astype(bool)
    np.savez_compressed(folder / name, **arrays)
    return name
