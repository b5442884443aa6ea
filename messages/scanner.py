"""The scanner's own messages (``dptpu_msgs/msg/...``): patterns, triggers, fringe frames, phase maps,
absolute phase and scan status.

Data flow of one scan (topics are defaults)::

    projector --Trigger--> camera --FringeFrame--> phase --PhaseMaps--> unwrap --AbsolutePhase--> cloud
    (/projector/trigger)  (/camera/image_raw)    (/scanner/phase)    (/scanner/absolute_phase)

Every message of one scan carries the scan's ``sequence_id``; ``header.frame_id`` of camera-side data is
the camera optical frame (``scanner_optical_frame``).

Convention: image ``n`` (0-based) of an ``N``-step entry is ``I_n = A + B cos(phi + phase_offset +
shift_sign*2*pi*n/N)``, ``shift_sign = -1`` being Eq. (1) of the paper; ``phi = 2*pi*f*x_p/W`` with ``f``
the number of periods across the projector extent ``W`` along the fringe axis and ``x_p`` the 0-based
projector coordinate. Wrapped phase lies in ``[0, 2*pi)`` and ``phi = psi + 2*pi*k``, ``k = floor(phi/2pi)``
(Eq. (3) of the paper).
"""

from __future__ import annotations

import math

import numpy as np

from .schema import Message, array, message, nested, nested_list, scalar, sequence
from .sensor import Image
from .std import Header

__all__ = ["PATTERN_KINDS", "REFERENCE_KINDS", "PatternEntry", "PatternSequence", "Trigger", "FringeFrame",
           "FringeBurst", "TriggerBurst", "PhaseMaps", "AbsolutePhase", "ScanStatus"]

FRINGE_AXES = ("x", "y")
#: What a pattern is: one of an N-step phase-shifted set, or a reference frame (the projector full on, full off).
PATTERN_KINDS = ("phase", "white", "black")
REFERENCE_KINDS = ("white", "black")


def _check_fringe_axis(owner: str, fringe_axis: str) -> None:
    if fringe_axis not in FRINGE_AXES:
        raise ValueError(f"{owner}.fringe_axis must be 'x' or 'y'; got {fringe_axis!r}")


def _check_one_scan_in_order(owner: str, triggers: list) -> None:
    """ValueError unless ``triggers`` are of one scan with ``pattern_index`` increasing."""
    scans = {trigger.sequence_id for trigger in triggers}
    if len(scans) > 1:
        raise ValueError(f"{owner}.triggers must be of one scan; got sequence_ids {sorted(scans)}")
    indices = [trigger.pattern_index for trigger in triggers]
    if any(b <= a for a, b in zip(indices, indices[1:])):
        raise ValueError(f"{owner}.triggers' pattern_index must increase; got {indices}")


def _extent_px(fringe_axis: str, projector_width: int, projector_height: int) -> int:
    return projector_width if fringe_axis == "x" else projector_height


@message("dptpu_msgs/msg/PatternEntry", version=2)
class PatternEntry(Message):
    """One ``N``-step phase-shifted fringe pattern set of a :class:`PatternSequence`, or one reference frame.

    Attributes
    ----------
    kind : str
        ``"phase"`` (default): a fringe set; ``"white"`` or ``"black"``: one frame with the projector full on or
        full off (the texture, :mod:`dptpu.fpp.texture`), ``frequency`` and ``period`` 0 and ``steps`` 1.
    frequency : float
        Fringe periods across the projector extent along the fringe axis (> 0; may be rational, e.g.
        10.9), or 0 when the entry is given by ``period``.
    period : float
        Fringe period in projector pixels (> 0), or 0 when the entry is given by ``frequency``.
        Exactly one of ``frequency`` and ``period`` is > 0.
    steps : int
        Number of phase steps ``N >= 3`` (uint32).
    phase_offset : float
        Radians added to every pattern of the entry.
    """

    frequency: float = scalar("float64")
    period: float = scalar("float64")
    steps: int = scalar("uint32")
    phase_offset: float = scalar("float64")
    kind: str = scalar("string", default="phase")

    @property
    def is_reference(self) -> bool:
        """A white or black reference frame, not a fringe set."""
        return self.kind in REFERENCE_KINDS

    def frequency_for(self, extent_px: float) -> float:
        """Periods across ``extent_px`` projector pixels: ``frequency``, or ``extent_px / period`` (0 for a
        reference frame)."""
        if self.is_reference:
            return 0.0
        return float(self.frequency) if self.frequency > 0 else float(extent_px) / float(self.period)

    def check_consistency(self) -> None:
        if self.kind not in PATTERN_KINDS:
            raise ValueError(f"PatternEntry.kind must be one of {', '.join(PATTERN_KINDS)}; got {self.kind!r}")
        if self.is_reference:
            if self.frequency != 0 or self.period != 0 or self.steps != 1:
                raise ValueError(f"a {self.kind} PatternEntry is one frame without fringes: frequency 0, period 0, "
                                 f"steps 1; got {self.frequency}, {self.period}, {self.steps}")
            return
        if not (math.isfinite(self.frequency) and math.isfinite(self.period) and self.frequency >= 0
                and self.period >= 0 and (self.frequency > 0) != (self.period > 0)):
            raise ValueError("PatternEntry needs exactly one of frequency (periods across the extent) and period "
                             f"(projector pixels) > 0 and the other 0; got frequency {self.frequency}, "
                             f"period {self.period}")
        if self.steps < 3:
            raise ValueError(f"PatternEntry.steps must be >= 3; got {self.steps}")
        if not math.isfinite(self.phase_offset):
            raise ValueError(f"PatternEntry.phase_offset must be finite; got {self.phase_offset}")


@message("dptpu_msgs/msg/PatternSequence", version=2)
class PatternSequence(Message):
    """The fringe patterns of one scan, in projection order: entry by entry, step ``n = 0..N-1`` each.

    Attributes
    ----------
    header : Header
        Stamp of publication; ``frame_id`` the projector's frame.
    entries : list of PatternEntry
        Pattern sets in projection order (highest frequency first is customary).
    fringe_axis : str
        ``"x"``: phase varies along projector columns (vertical stripes), extent = projector width;
        ``"y"``: along rows, extent = projector height.
    projector_width, projector_height : int
        Projector resolution, pixels (> 0).
    shift_sign : int
        -1 (Eq. (1) of the paper) or +1: image ``n`` is ``A + B cos(phi + shift_sign*2*pi*n/N)``.
    """

    header: Header = nested(Header)
    entries: list = nested_list(PatternEntry)
    fringe_axis: str = scalar("string", default="x")
    projector_width: int = scalar("uint32")
    projector_height: int = scalar("uint32")
    shift_sign: int = scalar("int8", default=-1)

    @property
    def projector_size(self) -> tuple[int, int]:
        """``(width, height)`` of the projector, pixels."""
        return (self.projector_width, self.projector_height)

    @property
    def extent_px(self) -> int:
        """Projector pixels along the fringe axis (the ``W`` of ``phi = 2*pi*f*x_p/W``)."""
        return _extent_px(self.fringe_axis, self.projector_width, self.projector_height)

    @property
    def pattern_count(self) -> int:
        """Total number of patterns, ``sum(entry.steps)``."""
        return sum(entry.steps for entry in self.entries)

    def frequencies(self) -> list[float]:
        """Frequency of every entry (periods across the extent; 0 for a reference frame), in entry order."""
        return [entry.frequency_for(self.extent_px) for entry in self.entries]

    def locate(self, pattern_index: int) -> tuple[int, int]:
        """``(entry_index, step)`` of pattern ``pattern_index`` (0-based, projection order)."""
        if isinstance(pattern_index, bool) or not isinstance(pattern_index, (int, np.integer)) \
                or not 0 <= pattern_index < self.pattern_count:
            raise ValueError(f"pattern_index must be an int in [0, {self.pattern_count}); got {pattern_index!r}")
        remaining = int(pattern_index)
        for entry_index, entry in enumerate(self.entries):
            if remaining < entry.steps:
                return entry_index, remaining
            remaining -= entry.steps
        raise AssertionError("unreachable: pattern_index was checked against pattern_count")

    def check_consistency(self) -> None:
        _check_fringe_axis("PatternSequence", self.fringe_axis)
        if self.shift_sign not in (-1, 1):
            raise ValueError(f"PatternSequence.shift_sign must be -1 or +1; got {self.shift_sign}")
        if self.projector_width < 1 or self.projector_height < 1:
            raise ValueError("PatternSequence projector size must be positive; got "
                             f"({self.projector_width}, {self.projector_height})")


@message("dptpu_msgs/msg/Trigger", version=2)
class Trigger(Message):
    """The projector shows one pattern: published when it is on screen, so the camera may expose.

    Attributes
    ----------
    header : Header
        ``stamp``: when the pattern is displayed (exposure may start); ``frame_id``: projector frame.
    sequence_id : int
        Scan counter, the same for every message of one scan (uint32, wraps around).
    pattern_index : int
        0-based index of the pattern in the scan's :class:`PatternSequence` (projection order).
    pattern_count : int
        Number of patterns in the scan (``pattern_index < pattern_count``); 0 if unknown.
    frequency : float
        Fringe periods across the projector extent of this pattern's entry.
    steps : int
        ``N`` of this pattern's entry (>= 3), or 0 if unknown.
    step : int
        Phase step ``n`` in ``[0, N)``: the pattern is ``A + B cos(phi + shift_sign*2*pi*n/N)``.
    kind : str
        ``"phase"`` (default), or ``"white"`` / ``"black"`` for a reference frame (``frequency`` 0, ``steps`` 1).
    """

    header: Header = nested(Header)
    sequence_id: int = scalar("uint32")
    pattern_index: int = scalar("uint32")
    pattern_count: int = scalar("uint32")
    frequency: float = scalar("float64")
    steps: int = scalar("uint32")
    step: int = scalar("uint32")
    kind: str = scalar("string", default="phase")

    def check_consistency(self) -> None:
        if self.kind not in PATTERN_KINDS:
            raise ValueError(f"Trigger.kind must be one of {', '.join(PATTERN_KINDS)}; got {self.kind!r}")
        if self.pattern_count and self.pattern_index >= self.pattern_count:
            raise ValueError(f"Trigger.pattern_index must be < pattern_count {self.pattern_count}; "
                             f"got {self.pattern_index}")
        if self.steps and self.step >= self.steps:
            raise ValueError(f"Trigger.step must be < steps {self.steps}; got {self.step}")


@message("dptpu_msgs/msg/TriggerBurst", version=1)
class TriggerBurst(Message):
    """The Triggers of consecutive patterns of one scan in one message: an entry's ``N``, published with its last.

    For a subscriber that needs an entry's patterns together, not each the moment it shows (the sim node, which
    answers with the entry's frames as one :class:`FringeBurst`): one message an entry instead of ``N`` (issue 20).

    Attributes
    ----------
    header : Header
        ``stamp``: when the last pattern was displayed; ``frame_id``: projector frame.
    triggers : list of Trigger
        One a pattern, in order (each with its own display stamp): one ``sequence_id``, ``pattern_index``
        increasing.
    """

    header: Header = nested(Header)
    triggers: list = nested_list(Trigger)

    def check_consistency(self) -> None:
        _check_one_scan_in_order("TriggerBurst", self.triggers)


@message("dptpu_msgs/msg/FringeFrame", version=2)
class FringeFrame(Message):
    """One camera frame of a fringe pattern and the trigger it answers.

    Attributes
    ----------
    image : Image
        The frame (``mono8`` or ``mono16``, digital numbers); ``image.header.stamp`` = exposure start.
    trigger : Trigger
        The pattern shown during the exposure (``sequence_id``, ``pattern_index``, ``frequency``,
        ``step``).
    """

    image: Image = nested(Image)
    trigger: Trigger = nested(Trigger)


@message("dptpu_msgs/msg/FringeBurst", version=1)
class FringeBurst(Message):
    """Consecutive camera frames of one scan in one message: an entry's ``N`` phase-shifted frames, or a reference.

    The camera side publishes one burst where it would publish ``N`` :class:`FringeFrame` s: a scan then costs each
    subscriber two or three message receptions instead of 24 (docs/benchmarks.md, issue 20). ``image`` is a valid
    ``sensor_msgs/Image`` on its own: the frames stacked top to bottom.

    Attributes
    ----------
    image : Image
        The frames, ``mono8`` or ``mono16``, stacked: frame ``k`` is rows ``[k*H, (k+1)*H)``, ``H = image.height /
        len(triggers)``; ``image.header.stamp`` = the last frame's exposure start (the burst exists once it is in).
    triggers : list of Trigger
        The pattern of each frame, in order; all of one ``sequence_id``, ``pattern_index`` strictly increasing.
    """

    image: Image = nested(Image)
    triggers: list = nested_list(Trigger)

    @property
    def frame_height(self) -> int:
        """Rows of one frame (0 for an empty burst)."""
        return self.image.height // len(self.triggers) if self.triggers else 0

    def frames(self) -> np.ndarray:
        """The frames as an (N, H, W) view of ``image`` (read-only after decoding)."""
        stacked = self.image.to_array()
        if stacked.ndim != 2:
            raise ValueError(f"FringeBurst.image must be mono8 or mono16 (one channel); got {self.image.encoding!r}")
        return stacked.reshape(len(self.triggers), self.frame_height, stacked.shape[1])

    def check_consistency(self) -> None:
        if not self.triggers:
            if self.image.height:
                raise ValueError(f"FringeBurst.triggers must hold one Trigger per frame; got none for an image of "
                                 f"{self.image.height} rows")
            return
        if self.image.height % len(self.triggers):
            raise ValueError(f"FringeBurst.image.height {self.image.height} must be a multiple of the "
                             f"{len(self.triggers)} frames (one Trigger each)")
        _check_one_scan_in_order("FringeBurst", self.triggers)

    @classmethod
    def from_frames(cls, frames: np.ndarray, triggers: list, *, header: Header | None = None) -> FringeBurst:
        """A burst of ``frames`` (N, H, W) uint8 or uint16 (a view when C-contiguous) answering ``triggers``."""
        if not isinstance(frames, np.ndarray) or frames.ndim != 3 or frames.shape[0] != len(triggers):
            raise ValueError(f"frames must be an (N, H, W) array with N = {len(triggers)} triggers; got "
                             f"{getattr(frames, 'shape', None)!r}")
        stacked = frames.reshape(-1, frames.shape[2])
        return cls(image=Image.from_array(stacked, header=header), triggers=list(triggers))


@message("dptpu_msgs/msg/PhaseMaps", version=2)
class PhaseMaps(Message):
    """Wrapped phase and modulation of every frequency of one scan (Eq. (2) of the paper).

    Attributes
    ----------
    header : Header
        Stamp of the scan's last frame; ``frame_id``: camera optical frame.
    sequence_id : int
        The scan (uint32).
    fringe_axis : str
        ``"x"`` or ``"y"`` (see :class:`PatternSequence`).
    projector_width, projector_height : int
        Projector resolution, pixels (0 if unknown).
    frequencies : ndarray (F,) float64
        Periods across the projector extent of each phase map, in the order of ``phases``.
    phases : ndarray (F, H, W) float32
        Wrapped phase ``psi`` in radians, in ``[0, 2*pi)``.
    modulation : ndarray (F, H, W) float32
        Fringe modulation ``B`` in the images' digital numbers (>= 0).
    valid : ndarray (H, W) bool
        Pixels whose phases are usable (enough modulation, not saturated).
    steps : ndarray (F,) uint32, or empty
        Phase steps ``N`` of the sequence behind each map, in the order of ``phases``, each >= 3; the frames were
        integer (``mono8`` / ``mono16``), so ``N`` and ``modulation`` give the phase noise their rounding leaves
        (:func:`dptpu.fpp.fringe_noise.quantization_phase_noise`). Empty (the default) when the publisher does not
        know them: the unwrap node then judges the two frequencies' agreement without that floor.
    """

    header: Header = nested(Header)
    sequence_id: int = scalar("uint32")
    fringe_axis: str = scalar("string", default="x")
    projector_width: int = scalar("uint32")
    projector_height: int = scalar("uint32")
    frequencies: np.ndarray = sequence("float64")
    phases: np.ndarray = array("float32", ("F", "H", "W"))
    modulation: np.ndarray = array("float32", ("F", "H", "W"))
    valid: np.ndarray = array("bool", ("H", "W"))
    steps: np.ndarray = sequence("uint32")

    @property
    def extent_px(self) -> int:
        """Projector pixels along the fringe axis (0 if unknown)."""
        return _extent_px(self.fringe_axis, self.projector_width, self.projector_height)

    def check_consistency(self) -> None:
        _check_fringe_axis("PhaseMaps", self.fringe_axis)
        if self.modulation.shape != self.phases.shape:
            raise ValueError(f"PhaseMaps.modulation must have the shape of phases {self.phases.shape}; "
                             f"got {self.modulation.shape}")
        if self.valid.shape != self.phases.shape[1:]:
            raise ValueError(f"PhaseMaps.valid must have shape (H, W) = {self.phases.shape[1:]}; "
                             f"got {self.valid.shape}")
        if len(self.frequencies) != self.phases.shape[0]:
            raise ValueError(f"PhaseMaps.frequencies must have one entry per phase map (F = {self.phases.shape[0]}); "
                             f"got {len(self.frequencies)}")
        if len(self.steps) not in (0, self.phases.shape[0]) or np.any(np.asarray(self.steps) < 3):
            raise ValueError(f"PhaseMaps.steps must be empty or one count >= 3 per phase map (F = "
                             f"{self.phases.shape[0]}); got {np.asarray(self.steps).tolist()}")


@message("dptpu_msgs/msg/AbsolutePhase", version=1)
class AbsolutePhase(Message):
    """Unwrapped phase of one frequency: ``Psi = psi + 2*pi*k`` (Eq. (3) of the paper).

    Attributes
    ----------
    header : Header
        Stamp of the scan's last frame; ``frame_id``: camera optical frame.
    sequence_id : int
        The scan (uint32).
    frequency : float
        Periods across the projector extent of the unwrapped phase.
    fringe_axis : str
        ``"x"`` or ``"y"``.
    projector_width, projector_height : int
        Projector resolution, pixels (0 if unknown); the projector coordinate is
        ``x_p = Psi * extent / (2*pi*frequency)``.
    absolute_phase : ndarray (H, W) float32
        ``Psi`` in radians, in ``[0, 2*pi*frequency)``; NaN or any value where not ``valid``.
    fringe_order : ndarray (H, W) int32
        ``k = floor(Psi / 2pi)``.
    valid : ndarray (H, W) bool
        Pixels with a trusted absolute phase.
    reliability : ndarray (H, W) float32
        Per-pixel confidence in ``[0, 1]``: classical methods ``1 - 2*|q - round(q)|`` of the quantity the method
        rounds (1 = exactly an integer); ``"dptpu"`` the network's confidence (``dptpu.fpp.confidence``).
    method : str
        The unwrapping method, e.g. ``"mf"``, ``"mw"``, ``"nt"``, ``"heterodyne"``, ``"graycode"``,
        ``"dptpu"``.
    """

    header: Header = nested(Header)
    sequence_id: int = scalar("uint32")
    frequency: float = scalar("float64")
    fringe_axis: str = scalar("string", default="x")
    projector_width: int = scalar("uint32")
    projector_height: int = scalar("uint32")
    absolute_phase: np.ndarray = array("float32", ("H", "W"))
    fringe_order: np.ndarray = array("int32", ("H", "W"))
    valid: np.ndarray = array("bool", ("H", "W"))
    reliability: np.ndarray = array("float32", ("H", "W"))
    method: str = scalar("string")

    @property
    def projector_size(self) -> tuple[int, int]:
        """``(width, height)`` of the projector, pixels."""
        return (self.projector_width, self.projector_height)

    @property
    def extent_px(self) -> int:
        """Projector pixels along the fringe axis (0 if unknown)."""
        return _extent_px(self.fringe_axis, self.projector_width, self.projector_height)

    def check_consistency(self) -> None:
        _check_fringe_axis("AbsolutePhase", self.fringe_axis)
        shape = self.absolute_phase.shape
        for name in ("fringe_order", "valid", "reliability"):
            other = getattr(self, name).shape
            if other != shape:
                raise ValueError(f"AbsolutePhase.{name} must have the shape of absolute_phase {shape}; got {other}")


@message("dptpu_msgs/msg/ScanStatus", version=1)
class ScanStatus(Message):
    """Progress and health of one scan, published by each processing node.

    Attributes
    ----------
    header : Header
        When the status was made.
    sequence_id : int
        The scan (uint32).
    level : int
        ``OK = 0``, ``WARN = 1``, ``ERROR = 2``, ``STALE = 3`` (as ``diagnostic_msgs/DiagnosticStatus``).
    state : str
        ``"idle"``, ``"capturing"``, ``"processing"``, ``"done"`` or ``"failed"``.
    reason : str
        Human-readable reason for the level and state (empty when OK).
    node : str
        Fully qualified name of the reporting node, e.g. ``"/scanner/phase"``.
    frames_expected, frames_received, frames_dropped : int
        Fringe frames of the scan: expected from the pattern sequence, received, and dropped.
    decode_errors : int
        Malformed messages refused while working on the scan.
    valid_pixels, total_pixels : int
        Pixels with a valid result, and all pixels (0 before results exist).
    duration_s : float
        Seconds from the scan's first trigger to this status.
    """

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3
    STATES = ("idle", "capturing", "processing", "done", "failed")

    header: Header = nested(Header)
    sequence_id: int = scalar("uint32")
    level: int = scalar("uint8")
    state: str = scalar("string", default="idle")
    reason: str = scalar("string")
    node: str = scalar("string")
    frames_expected: int = scalar("uint32")
    frames_received: int = scalar("uint32")
    frames_dropped: int = scalar("uint32")
    decode_errors: int = scalar("uint32")
    valid_pixels: int = scalar("uint32")
    total_pixels: int = scalar("uint32")
    duration_s: float = scalar("float64")

    def check_consistency(self) -> None:
        if self.level > self.STALE:
            raise ValueError(f"ScanStatus.level must be OK (0), WARN (1), ERROR (2) or STALE (3); got {self.level}")
        if self.state not in self.STATES:
            raise ValueError(f"ScanStatus.state must be one of {', '.join(self.STATES)}; got {self.state!r}")
        if self.valid_pixels > self.total_pixels:
            raise ValueError(f"ScanStatus.valid_pixels must be <= total_pixels {self.total_pixels}; "
                             f"got {self.valid_pixels}")
