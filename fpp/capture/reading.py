"""Reading a capture folder: ``capture.yaml`` parsed and validated into a :class:`Capture` (no pixels read)."""

from __future__ import annotations

from pathlib import Path

import yaml

from ..text_files import read_text_file
from .document_checks import DocumentChecker
from .model import (
    BIT_DEPTHS,
    CAPTURE_FILE,
    CAPTURE_FORMAT,
    FRINGE_AXES,
    GRAYCODE_KEYS,
    PHASE_KEYS,
    REFERENCE_NAMES,
    TOP_LEVEL_KEYS,
    Capture,
    GraycodeSequence,
    PatternLevels,
    PhaseSequence,
    format_number,
)

__all__ = ["read_capture", "parse_capture", "resolve_path", "MAX_STEPS", "MAX_GRAY_BITS"]

#: Most phase steps of one sequence (the paper's labels use 12; hundreds would already be unusual).
MAX_STEPS = 1000
#: Most Gray-code bits: 2**24 code steps, more than any projector has pixels along an axis.
MAX_GRAY_BITS = 24


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
    text = read_text_file(yaml_path, f"a {CAPTURE_FILE} ({CAPTURE_FORMAT}, docs/capture-format.md)")
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{yaml_path}: not valid YAML ({' '.join(str(exc).split())})") from None
    return parse_capture(document, yaml_path.parent.resolve(), str(yaml_path))


def parse_capture(document, root: Path, source: str) -> Capture:
    """Validate a parsed ``capture.yaml`` document; ``source`` names the file in messages."""
    spec = DocumentChecker(source)
    if not isinstance(document, dict):
        spec.fail(f"must be a mapping of keys (format: {CAPTURE_FORMAT}, camera, ...); "
                  f"got {type(document).__name__}")
    fmt = spec.require(document, "format")
    if fmt != CAPTURE_FORMAT:
        spec.fail(f"format must be '{CAPTURE_FORMAT}'; got {fmt!r}")

    camera = spec.mapping(spec.require(document, "camera"), "camera")
    camera_size = spec.size(spec.require(camera, "size", "camera.size"), "camera.size")
    bit_depth = spec.require(camera, "bit_depth", "camera.bit_depth")
    if isinstance(bit_depth, bool) or bit_depth not in BIT_DEPTHS:
        spec.fail(f"camera.bit_depth must be 8 or 16; got {bit_depth!r}")
    projector = spec.mapping(spec.require(document, "projector"), "projector")
    projector_size = spec.size(spec.require(projector, "size", "projector.size"), "projector.size")

    fringe_axis = spec.require(document, "fringe_axis")
    if fringe_axis not in FRINGE_AXES:
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
            if name not in REFERENCE_NAMES:
                spec.fail(f"references may hold 'white' and 'black'; got unknown key {name!r}")
            references[name] = resolve_path(root, spec.file_name(value, f"references.{name}"))
    calibration = ground_truth = None
    if document.get("calibration") is not None:
        calibration = resolve_path(root, spec.file_name(document["calibration"], "calibration"))
    if document.get("ground_truth") is not None:
        ground_truth = resolve_path(root, spec.file_name(document["ground_truth"], "ground_truth"))

    capture = Capture(
        root=root, camera_size=camera_size, bit_depth=int(bit_depth), projector_size=projector_size,
        fringe_axis=fringe_axis, phase_shift_sign=int(sign), sequences=sequences, pattern=pattern,
        references=references, calibration=calibration, ground_truth=ground_truth,
        extras={k: v for k, v in document.items() if k not in TOP_LEVEL_KEYS},
    )
    folders = [p for p in _listed_files(capture) if p.is_dir()]
    if folders:
        names = ", ".join(_display(root, p) for p in folders)
        raise ValueError(f"{source}: {len(folders)} listed file(s) are folders, not files: {names}")
    missing = [p for p in _listed_files(capture) if not p.is_file()]
    if missing:
        names = ", ".join(_display(root, p) for p in missing)
        raise FileNotFoundError(f"{source}: {len(missing)} listed file(s) do not exist: {names} "
                                f"(relative names are looked up in {root})")
    return capture


def _parse_pattern(spec: DocumentChecker, raw) -> PatternLevels:
    raw = spec.mapping(raw, "pattern")
    offset = spec.number(spec.require(raw, "offset", "pattern.offset"), "pattern.offset")
    amplitude = spec.number(spec.require(raw, "amplitude", "pattern.amplitude"), "pattern.amplitude")
    if amplitude <= 0 or offset - amplitude < 0 or offset + amplitude > 1:
        spec.fail(f"pattern offset +- amplitude must stay within [0, 1] of full scale with amplitude > 0; "
                  f"got offset={offset}, amplitude={amplitude}")
    return PatternLevels(offset=offset, amplitude=amplitude)


def _parse_sequence(spec: DocumentChecker, raw, index: int, root: Path, extent: int):
    where = f"sequences[{index}]"
    raw = spec.mapping(raw, where)
    kind = raw.get("kind", "phase")
    if kind == "phase":
        return _parse_phase_sequence(spec, raw, index, root, extent)
    if kind == "graycode":
        return _parse_graycode_sequence(spec, raw, index, root, extent)
    spec.fail(f"{where}.kind must be 'phase' (the default) or 'graycode'; got {kind!r}")


def _parse_phase_sequence(spec: DocumentChecker, raw: dict, index: int, root: Path, extent: int) -> PhaseSequence:
    where = f"sequences[{index}]"
    has_frequency, has_period = raw.get("frequency") is not None, raw.get("period") is not None
    if has_frequency == has_period:
        spec.fail(f"{where}: give exactly one of 'frequency' and 'period'; got "
                  f"{'both' if has_frequency else 'neither'}")
    frequency = period = None
    if has_frequency:  # a fringe period of fewer than 2 projector pixels cannot be projected (Nyquist)
        frequency = spec.positive(raw["frequency"], f"{where}.frequency")
        if frequency > extent / 2:
            spec.fail(f"{where}.frequency must be at most {format_number(extent / 2)} (a period of 2 projector "
                      f"pixels over the extent {extent} along the fringe axis); got {frequency:g}")
    else:
        period = spec.positive(raw["period"], f"{where}.period")
        if period < 2:
            spec.fail(f"{where}.period must be at least 2 projector pixels; got {period:g}")
    steps = spec.integer(spec.require(raw, "steps", f"{where}.steps"), f"{where}.steps", minimum=3,
                         maximum=MAX_STEPS)
    declared = f"frequency {format_number(frequency)}" if has_frequency else f"period {format_number(period)}"
    label = f"sequence {index} ({declared})"
    images = spec.file_list(spec.require(raw, "images", f"{where}.images"), f"{where}.images")
    if len(images) != steps:
        spec.fail(f"{label}: {len(images)} images listed but steps is {steps}")
    phase_offset = raw.get("phase_offset")
    phase_offset = 0.0 if phase_offset is None else spec.number(phase_offset, f"{where}.phase_offset")
    return PhaseSequence(
        steps=steps, images=tuple(resolve_path(root, name) for name in images), frequency=frequency,
        period=period, phase_offset=phase_offset,
        extras={k: v for k, v in raw.items() if k not in PHASE_KEYS},
    )


def _parse_graycode_sequence(spec: DocumentChecker, raw: dict, index: int, root: Path, extent: int) -> GraycodeSequence:
    where = f"sequences[{index}]"
    bits = spec.integer(spec.require(raw, "bits", f"{where}.bits"), f"{where}.bits", minimum=1, maximum=MAX_GRAY_BITS)
    period = spec.positive(spec.require(raw, "period", f"{where}.period"), f"{where}.period")
    label = f"sequence {index} (graycode, period {format_number(period)})"
    if 2**bits * period < extent:
        spec.fail(f"{label}: {bits} bits cover 2**{bits} * {format_number(period)} = "
                  f"{format_number(2**bits * period)} projector pixels, less than the extent {extent} "
                  f"along the fringe axis")
    images = spec.file_list(spec.require(raw, "images", f"{where}.images"), f"{where}.images")
    if len(images) != bits:
        spec.fail(f"{label}: {len(images)} images listed but bits is {bits}")
    inverse: tuple[Path, ...] | None = None
    if raw.get("inverse") is not None:
        inverse_names = spec.file_list(raw["inverse"], f"{where}.inverse")
        if len(inverse_names) != bits:
            spec.fail(f"{label}: {len(inverse_names)} inverse images listed but bits is {bits}")
        inverse = tuple(resolve_path(root, name) for name in inverse_names)
    complementary = complementary_inverse = None
    if raw.get("complementary") is not None:
        complementary = resolve_path(root, spec.file_name(raw["complementary"], f"{where}.complementary"))
    if raw.get("complementary_inverse") is not None:
        if complementary is None or inverse is None:
            spec.fail(f"{label}: complementary_inverse needs both complementary and inverse")
        complementary_inverse = resolve_path(
            root, spec.file_name(raw["complementary_inverse"], f"{where}.complementary_inverse"))
    if inverse is not None and complementary is not None and complementary_inverse is None:
        spec.fail(f"{label}: missing key '{where}.complementary_inverse' (required when both inverse "
                  f"and complementary are given: the complementary bit needs its own inverse)")
    return GraycodeSequence(
        bits=bits, period=period, images=tuple(resolve_path(root, name) for name in images), inverse=inverse,
        complementary=complementary, complementary_inverse=complementary_inverse,
        extras={k: v for k, v in raw.items() if k not in GRAYCODE_KEYS},
    )


def resolve_path(root: Path, name: str) -> Path:
    """``root / name``; an absolute ``name`` stays as it is."""
    return root / Path(name).expanduser()


def _display(root: Path, path: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def _listed_files(capture: Capture) -> list[Path]:
    files: list[Path] = []
    for sequence in capture.sequences:
        files.extend(sequence.images)
        if isinstance(sequence, GraycodeSequence):
            files.extend(sequence.inverse or ())
            files.extend(p for p in (sequence.complementary, sequence.complementary_inverse) if p is not None)
    files.extend(capture.references.values())
    files.extend(p for p in (capture.calibration, capture.ground_truth) if p is not None)
    return files
