"""Assemble the fringe frames of one scan by ``sequence_id``: pure logic, no graph and no sockets.

A scan is every pattern of one projector sequence: entries (frequencies) x phase steps, e.g. 16 x 4 then
1 x 4 = 8 frames. The camera publishes one :class:`~dptpu.messages.FringeFrame` per pattern, carrying the
:class:`~dptpu.messages.Trigger` it answers (``sequence_id``, ``pattern_index``, ``pattern_count``,
``frequency``, ``steps``, ``step``). :class:`SequenceAssembler` collects them per ``sequence_id`` and
hands out an :class:`AssembledScan` (the frames of each entry, in step order, as received) once every
pattern is there; :meth:`SequenceAssembler.slot` tells where a frame it kept sits, so a caller can work on each
frame as it arrives (the phase node accumulates Eq. (2) per frame).

Where the layout comes from (the first that applies, fixed per scan when its first frame arrives):

1. a :class:`ScanLayout` given with :meth:`SequenceAssembler.set_layout` (the node builds it from the
   projector's ``PatternSequence``): each frame must sit where the layout says (``locate(pattern_index)``
   gives its entry and step; its frequency and step must agree);
2. the triggers alone: ``pattern_count > 0`` and each frame's ``frequency``, ``steps`` and ``step``; the
   entries are ordered by their first ``pattern_index`` and each must occupy the ``steps`` consecutive
   indices ``start + step``.

Rules (each outcome carries a human-readable reason):

- frames of two scans are never mixed: everything is keyed by ``sequence_id``;
- a scan still incomplete ``timeout_s`` after its first frame arrived is dropped (:class:`DroppedScan`,
  "incomplete ... missing ...");
- a frame that contradicts its scan (another image size or dtype, an unknown frequency, a step out of
  order with its ``pattern_index``, a duplicate index, a changed ``pattern_count``) fails that scan at
  once (:class:`DroppedScan`); the node also fails a scan through :meth:`SequenceAssembler.fail` when a
  frame cannot even be read;
- a frame of a scan that was already completed or dropped (within the last ``timeout_s``) is refused
  (:class:`RejectedFrame`), so a late frame never starts a half scan; after that the id may be reused
  (a restarted projector counts from 0 again);
- at most ``max_pending_scans`` scans wait at once; a new one drops the oldest ("superseded").

Time is passed in (``now_s``, any monotonic clock in seconds), so the logic is deterministic to test.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TypedDict

import numpy as np

from dptpu.fpp.frequencies import same_frequency
from dptpu.fpp.scan_phase import ImageSlot
from dptpu.messages.scanner import REFERENCE_KINDS

__all__ = [
    "AssembledScan",
    "DroppedScan",
    "FrameInfo",
    "RejectedFrame",
    "ScanLayout",
    "SequenceAssembler",
]

@dataclass(frozen=True, eq=False)
class FrameInfo:
    """What the assembler needs of one fringe frame.

    Attributes
    ----------
    sequence_id : int
        Scan counter of the trigger.
    pattern_index, pattern_count : int
        0-based index of the pattern in the scan, and the scan's number of patterns (0 = unknown).
    frequency : float
        Periods across the projector extent of the pattern's entry (0 = unknown).
    steps, step : int
        ``N`` of the entry (0 = unknown) and the phase step ``n`` in ``[0, N)``.
    image : ndarray (H, W)
        The camera frame, digital numbers (uint8 or uint16); kept by reference (no copy) until the scan is handed out.
    stamp_ns : int
        Exposure start, ns since the epoch.
    kind : str
        ``"phase"``, or ``"white"`` / ``"black"`` for a reference frame (the projector full on / off).
    """

    sequence_id: int
    pattern_index: int
    pattern_count: int
    frequency: float
    steps: int
    step: int
    image: np.ndarray
    stamp_ns: int = 0
    kind: str = "phase"

    def describe(self) -> str:
        if self.kind in REFERENCE_KINDS:
            return f"pattern {self.pattern_index} ({self.kind})"
        return (f"pattern {self.pattern_index} (f={self.frequency:g}, step {self.step}"
                f"{f' of {self.steps}' if self.steps else ''})")


@dataclass(frozen=True)
class ScanLayout:
    """The patterns of a scan in projection order: entry ``e`` has ``steps[e]`` frames of ``frequencies[e]``.

    Attributes
    ----------
    frequencies : tuple of float
        Periods across the projector extent, one per entry.
    steps : tuple of int
        Phase steps ``N >= 3`` per entry.
    phase_offsets : tuple of float
        Radians per entry (image ``n`` is ``A + B cos(phi + phase_offset + shift_sign*2*pi*n/N)``).
    shift_sign : int
        -1 (the paper's Eq. (1)) or +1.
    fringe_axis : str
        ``"x"`` or ``"y"``.
    projector_size : (int, int)
        Projector ``(width, height)``, pixels; ``(0, 0)`` when unknown.
    references : tuple of str
        Reference frames after the fringe sets, one pattern each: ``"white"``, ``"black"``.
    """

    frequencies: tuple
    steps: tuple
    phase_offsets: tuple = ()
    shift_sign: int = -1
    fringe_axis: str = "x"
    projector_size: tuple = (0, 0)
    references: tuple = ()

    def __post_init__(self):
        frequencies = tuple(float(f) for f in self.frequencies)
        steps = tuple(int(n) for n in self.steps)
        offsets = tuple(float(o) for o in self.phase_offsets) or (0.0,) * len(frequencies)
        if not frequencies or len(steps) != len(frequencies) or len(offsets) != len(frequencies):
            raise ValueError(f"ScanLayout needs one steps and one phase_offset per frequency; got frequencies "
                             f"{list(frequencies)}, steps {list(steps)}, phase_offsets {list(offsets)}")
        if any(not math.isfinite(f) or f <= 0 for f in frequencies):
            raise ValueError(f"ScanLayout frequencies must be finite and > 0; got {list(frequencies)}")
        if any(n < 3 for n in steps):
            raise ValueError(f"ScanLayout steps must be >= 3 per entry; got {list(steps)}")
        if self.shift_sign not in (-1, 1):
            raise ValueError(f"ScanLayout.shift_sign must be -1 or +1; got {self.shift_sign}")
        if self.fringe_axis not in ("x", "y"):
            raise ValueError(f"ScanLayout.fringe_axis must be 'x' or 'y'; got {self.fringe_axis!r}")
        object.__setattr__(self, "frequencies", frequencies)
        object.__setattr__(self, "steps", steps)
        object.__setattr__(self, "phase_offsets", offsets)
        object.__setattr__(self, "projector_size", tuple(int(v) for v in self.projector_size))
        references = tuple(str(kind) for kind in self.references)
        if any(kind not in REFERENCE_KINDS for kind in references) or len(set(references)) != len(references):
            raise ValueError(f"ScanLayout references must be white and/or black, once each; got {list(references)}")
        object.__setattr__(self, "references", references)

    @property
    def fringe_count(self) -> int:
        """Patterns of the fringe sets (the reference frames follow them)."""
        return sum(self.steps)

    @property
    def pattern_count(self) -> int:
        return sum(self.steps) + len(self.references)

    def reference_at(self, pattern_index: int) -> str | None:
        """``"white"`` / ``"black"`` when pattern ``pattern_index`` is a reference frame, else None."""
        offset = int(pattern_index) - self.fringe_count
        return self.references[offset] if 0 <= offset < len(self.references) else None

    def locate(self, pattern_index: int) -> tuple[int, int]:
        """``(entry, step)`` of a 0-based pattern index of the fringe sets; ValueError outside
        ``[0, fringe_count)`` (a reference frame: :meth:`reference_at`)."""
        if not 0 <= pattern_index < self.fringe_count:
            raise ValueError(f"pattern_index {pattern_index} is outside the scan's {self.fringe_count} fringe patterns")
        for entry, steps in enumerate(self.steps):
            if pattern_index < steps:
                return entry, pattern_index
            pattern_index -= steps
        raise AssertionError("unreachable: pattern_index was checked against pattern_count")

    @classmethod
    def from_pattern_sequence(cls, sequence) -> ScanLayout:
        """The layout of a :class:`dptpu.messages.PatternSequence` message (its reference frames must follow its
        fringe sets)."""
        entries = list(sequence.entries)
        fringes = [e for e in entries if not e.is_reference]
        references = [e.kind for e in entries if e.is_reference]
        if entries[:len(fringes)] != fringes:
            raise ValueError("the PatternSequence's reference frames (white, black) must follow its fringe sets")
        frequencies = sequence.frequencies()[:len(fringes)]
        return cls(frequencies=tuple(frequencies), steps=tuple(e.steps for e in fringes),
                   phase_offsets=tuple(e.phase_offset for e in fringes), shift_sign=sequence.shift_sign,
                   fringe_axis=sequence.fringe_axis, projector_size=sequence.projector_size,
                   references=tuple(references))


@dataclass(frozen=True, eq=False)
class AssembledScan:
    """Every frame of one scan, per entry.

    Attributes
    ----------
    sequence_id : int
    layout : ScanLayout
    images : tuple of tuple of ndarray
        Per entry, its ``N_e`` frames (H, W) in step order ``n = 0..N_e-1``, as received (not copied).
    first_stamp_ns, last_stamp_ns : int
        Earliest and latest exposure start of the scan's frames.
    first_arrival_s : float
        When its first frame arrived (the assembler's clock).
    references : dict
        ``"white"`` / ``"black"`` -> its frame (H, W), as received.
    """

    sequence_id: int
    layout: ScanLayout
    images: tuple
    first_stamp_ns: int
    last_stamp_ns: int
    first_arrival_s: float
    references: dict = field(default_factory=dict)

    @cached_property
    def stacks(self) -> tuple:
        """One ``(N_e, H, W)`` array per entry, step order, the frames' dtype (stacked on first use: a copy)."""
        return tuple(np.stack(entry) for entry in self.images)

    @property
    def frame_count(self) -> int:
        """Frames of the fringe sets (the reference frames not counted)."""
        return sum(len(entry) for entry in self.images)

    def slot(self, pattern_index: int) -> ImageSlot:
        """:class:`ImageSlot` of pattern ``pattern_index`` by the scan's layout."""
        entry, step = self.layout.locate(int(pattern_index))
        return ImageSlot(entry_start=sum(self.layout.steps[:entry]), steps=self.layout.steps[entry], step=step,
                         phase_offset=self.layout.phase_offsets[entry], shift_sign=self.layout.shift_sign)

    def slots(self) -> list[ImageSlot]:
        """:class:`ImageSlot` of every pattern, in pattern order: the scan's final layout."""
        return [self.slot(index) for index in range(self.frame_count)]


@dataclass(frozen=True)
class DroppedScan:
    """A scan given up, with why: incomplete at its timeout, inconsistent, or superseded."""

    sequence_id: int
    reason: str
    frames_expected: int
    frames_received: int
    first_arrival_s: float


@dataclass(frozen=True)
class RejectedFrame:
    """A frame refused on its own, its scan being already completed or dropped."""

    sequence_id: int
    reason: str


@dataclass(eq=False)
class _Pending:
    sequence_id: int
    first_arrival_s: float
    layout: ScanLayout | None            # fixed when the first frame arrived; None = from the triggers
    pattern_count: int
    shape: tuple
    dtype: np.dtype
    frames: dict[int, FrameInfo] = field(default_factory=dict)  # pattern_index -> FrameInfo


class _Geometry(TypedDict):
    """The :class:`ScanLayout` fields of a scan laid out by its triggers."""

    shift_sign: int
    fringe_axis: str
    projector_size: tuple[int, ...]


class SequenceAssembler:
    """Collects frames per ``sequence_id`` until a scan is complete (see the module docstring).

    Parameters
    ----------
    timeout_s : float
        Seconds from a scan's first frame until it is dropped as incomplete, > 0; also how long the id of
        a finished scan is remembered to refuse its late frames.
    max_pending_scans : int
        Scans that may wait at once, >= 1.
    shift_sign, fringe_axis, projector_size
        Geometry used for scans laid out by their triggers (no :class:`ScanLayout` set).
    """

    def __init__(self, *, timeout_s: float, max_pending_scans: int = 4, shift_sign: int = -1,
                 fringe_axis: str = "x", projector_size=(0, 0)):
        if not (isinstance(timeout_s, (int, float)) and math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"timeout_s must be a number of seconds > 0; got {timeout_s!r}")
        if not isinstance(max_pending_scans, int) or max_pending_scans < 1:
            raise ValueError(f"max_pending_scans must be an integer >= 1; got {max_pending_scans!r}")
        if shift_sign not in (-1, 1):
            raise ValueError(f"shift_sign must be -1 or +1; got {shift_sign!r}")
        if fringe_axis not in ("x", "y"):
            raise ValueError(f"fringe_axis must be 'x' or 'y'; got {fringe_axis!r}")
        self.timeout_s = float(timeout_s)
        self.max_pending_scans = max_pending_scans
        self._geometry: _Geometry = {"shift_sign": shift_sign, "fringe_axis": fringe_axis,
                                     "projector_size": tuple(int(v) for v in projector_size)}
        self._layout: ScanLayout | None = None
        self._pending: dict[int, _Pending] = {}
        self._finished: dict[int, tuple[float, str]] = {}   # sequence_id -> (when, "completed" | "dropped")

    # -- configuration ----------------------------------------------------------------------------------

    @property
    def layout(self) -> ScanLayout | None:
        return self._layout

    def set_layout(self, layout: ScanLayout | None) -> None:
        """Use ``layout`` for scans that start from now on (None: lay scans out by their triggers)."""
        self._layout = layout

    @property
    def pending_ids(self) -> list[int]:
        """Sequence ids of the scans waiting for frames, oldest first."""
        return list(self._pending)

    # -- events -------------------------------------------------------------------------------------------

    def add(self, frame: FrameInfo, now_s: float) -> list:
        """Take one frame; returns the outcomes it caused, in order.

        Returns
        -------
        list of AssembledScan, DroppedScan, RejectedFrame
            Expired scans first (:meth:`expire`), then what this frame did: completed its scan, failed it,
            superseded an older one, or was refused.
        """
        events: list = self.expire(now_s)
        sequence_id = int(frame.sequence_id)
        if sequence_id in self._finished:
            _, how = self._finished[sequence_id]
            return events + [RejectedFrame(sequence_id, f"late frame {frame.describe()} of scan {sequence_id}, "
                                                        f"which was already {how}")]
        image = np.asarray(frame.image)
        if image.ndim != 2 or image.size == 0:
            return events + self._fail_new_or_pending(sequence_id, now_s, frame,
                                                      f"frame {frame.describe()} has image shape {image.shape}; "
                                                      "expected (H, W)")
        scan = self._pending.get(sequence_id)
        if scan is None:
            scan, problem = self._start(frame, image, now_s)
            if problem:
                return events + [self._finish_dropped(sequence_id, problem, frame.pattern_count, 1, now_s, now_s)]
            self._pending[sequence_id] = scan
            events += self._enforce_capacity(now_s)
        problem = self._check(scan, frame, image)
        if problem:
            return events + [self.fail(sequence_id, problem, now_s)]
        scan.frames[int(frame.pattern_index)] = frame
        if len(scan.frames) < scan.pattern_count:
            return events
        return events + [self._complete(scan, now_s)]

    def expire(self, now_s: float) -> list[DroppedScan]:
        """Drop the scans still incomplete ``timeout_s`` after their first frame; forget old finished ids."""
        finished = self._finished  # in the order the scans finished (_remember): the oldest first
        while finished:
            sequence_id, (when, _) = next(iter(finished.items()))
            if now_s - when <= self.timeout_s:
                break
            del finished[sequence_id]
        events = []
        for scan in [s for s in self._pending.values() if now_s - s.first_arrival_s > self.timeout_s]:
            events.append(self.fail(scan.sequence_id,
                                    f"incomplete after {self.timeout_s:g} s: received {len(scan.frames)} of "
                                    f"{scan.pattern_count} frames; missing {self._missing(scan)}", now_s))
        return events

    def fail(self, sequence_id: int, reason: str, now_s: float) -> DroppedScan:
        """Give up scan ``sequence_id`` (pending or not) with ``reason``; its later frames are refused."""
        scan = self._pending.pop(int(sequence_id), None)
        expected = scan.pattern_count if scan else 0
        received = len(scan.frames) if scan else 0
        first = scan.first_arrival_s if scan else now_s
        return self._finish_dropped(int(sequence_id), reason, expected, received, first, now_s)

    def slot(self, sequence_id: int, pattern_index: int) -> ImageSlot | None:
        """Where frame ``pattern_index`` of pending scan ``sequence_id`` sits (:class:`ImageSlot`), by the scan's
        layout or, for a scan laid out by its triggers, by the frame's own trigger; None when the scan is not
        pending or does not hold that frame (refused, failed, or completed: see :meth:`AssembledScan.slot`)."""
        scan = self._pending.get(int(sequence_id))
        frame = scan.frames.get(int(pattern_index)) if scan is not None else None
        if scan is None or frame is None or frame.kind in REFERENCE_KINDS:
            return None
        if scan.layout is not None:
            entry, step = scan.layout.locate(int(pattern_index))
            return ImageSlot(entry_start=int(pattern_index) - step, steps=scan.layout.steps[entry], step=step,
                             phase_offset=scan.layout.phase_offsets[entry], shift_sign=scan.layout.shift_sign)
        return ImageSlot(entry_start=int(frame.pattern_index) - int(frame.step), steps=int(frame.steps),
                         step=int(frame.step), phase_offset=0.0, shift_sign=self._geometry["shift_sign"])

    # -- internals --------------------------------------------------------------------------------------

    def _fail_new_or_pending(self, sequence_id, now_s, frame, reason) -> list:
        if sequence_id in self._pending:
            return [self.fail(sequence_id, reason, now_s)]
        return [self._finish_dropped(sequence_id, reason, frame.pattern_count, 1, now_s, now_s)]

    def _finish_dropped(self, sequence_id, reason, expected, received, first_arrival_s, now_s) -> DroppedScan:
        self._remember(sequence_id, now_s, "dropped")
        return DroppedScan(sequence_id=sequence_id, reason=reason, frames_expected=int(expected),
                           frames_received=int(received), first_arrival_s=first_arrival_s)

    def _remember(self, sequence_id: int, now_s: float, how: str) -> None:
        """Refuse frames of ``sequence_id`` for ``timeout_s`` from ``now_s``; kept in finishing order, so
        :meth:`expire` forgets from the front (once per frame, the ids of a second of scans: no full pass)."""
        self._finished.pop(sequence_id, None)
        self._finished[sequence_id] = (now_s, how)

    def _start(self, frame: FrameInfo, image: np.ndarray, now_s: float):
        layout = self._layout
        if layout is not None:
            count = layout.pattern_count
            if frame.pattern_count and frame.pattern_count != count:
                return None, (f"trigger pattern_count {frame.pattern_count} differs from the PatternSequence's "
                              f"{count} patterns")
        else:
            count = int(frame.pattern_count)
            if count <= 0:
                return None, (f"frame {frame.describe()} has pattern_count 0 and no PatternSequence is known: "
                              "cannot tell when the scan is complete")
        return _Pending(sequence_id=int(frame.sequence_id), first_arrival_s=now_s, layout=layout, pattern_count=count,
                        shape=image.shape, dtype=image.dtype), None

    def _check(self, scan: _Pending, frame: FrameInfo, image: np.ndarray) -> str | None:
        """Why ``frame`` does not fit ``scan`` (None when it fits). The frame's description is built only for a
        refusal, not for every frame that fits."""
        what = frame.describe  # called only in a refusal
        if image.shape != scan.shape or image.dtype != scan.dtype:
            return (f"frame {what()} is {image.shape[1]}x{image.shape[0]} {image.dtype}; the scan's first frame was "
                    f"{scan.shape[1]}x{scan.shape[0]} {scan.dtype}")
        if frame.pattern_count and frame.pattern_count != scan.pattern_count:
            return f"frame {what()} says pattern_count {frame.pattern_count}; the scan has {scan.pattern_count}"
        if not 0 <= frame.pattern_index < scan.pattern_count:
            return f"frame {what()} has pattern_index outside [0, {scan.pattern_count})"
        if frame.pattern_index in scan.frames:
            return f"duplicate frame for pattern_index {frame.pattern_index}"
        if scan.layout is not None:
            reference = scan.layout.reference_at(int(frame.pattern_index))
            if reference is not None or frame.kind in REFERENCE_KINDS:
                if frame.kind != (reference or "phase"):
                    return (f"frame {what()} is a {frame.kind} frame; the PatternSequence has "
                            f"{reference or 'a fringe pattern'} at pattern {frame.pattern_index}")
                return None
            entry, step = scan.layout.locate(int(frame.pattern_index))
            expected_f = scan.layout.frequencies[entry]
            if frame.frequency and not same_frequency(frame.frequency, expected_f):
                known = ", ".join(f"{f:g}" for f in scan.layout.frequencies)
                return (f"frame {what()}: unknown frequency {frame.frequency:g} for pattern {frame.pattern_index}; "
                        f"the PatternSequence has {expected_f:g} there (frequencies {known})")
            if (frame.steps and frame.steps != scan.layout.steps[entry]) or frame.step != step:
                return (f"frame {what()} is out of order: pattern {frame.pattern_index} is step {step} of "
                        f"{scan.layout.steps[entry]} at f={expected_f:g} in the PatternSequence")
            return None
        if frame.kind in REFERENCE_KINDS:
            if any(other.kind == frame.kind for other in scan.frames.values()):
                return f"frame {what()} repeats the scan's {frame.kind} frame"
            return None
        if not (math.isfinite(frame.frequency) and frame.frequency > 0) or frame.steps < 3:
            return (f"frame {what()} lacks its entry's frequency or steps (>= 3) and no PatternSequence is known; "
                    "cannot place it")
        if frame.step >= frame.steps:
            return f"frame {what()} has step >= steps"
        for other in scan.frames.values():
            if other.kind == "phase" and same_frequency(other.frequency, frame.frequency):
                if other.steps != frame.steps:
                    return (f"frame {what()} says steps {frame.steps} at f={frame.frequency:g}; an earlier frame said "
                            f"{other.steps}")
                if other.step == frame.step:
                    return f"frame {what()} repeats step {frame.step} at f={frame.frequency:g}"
                if other.pattern_index - other.step != frame.pattern_index - frame.step:
                    return (f"frame {what()} is out of order: step {frame.step} at pattern {frame.pattern_index}, but "
                            f"step {other.step} of f={frame.frequency:g} was pattern {other.pattern_index}")
        return None

    def _enforce_capacity(self, now_s: float) -> list[DroppedScan]:
        events = []
        while len(self._pending) > self.max_pending_scans:
            oldest = min(self._pending.values(), key=lambda s: s.first_arrival_s)
            events.append(self.fail(oldest.sequence_id,
                                    f"superseded: {len(self._pending) - 1} newer scans are pending (max_pending_scans "
                                    f"{self.max_pending_scans}); received {len(oldest.frames)} of "
                                    f"{oldest.pattern_count} frames; missing {self._missing(oldest)}", now_s))
        return events

    def _complete(self, scan: _Pending, now_s: float):
        layout = scan.layout if scan.layout is not None else self._layout_from_triggers(scan)
        if isinstance(layout, str):
            return self.fail(scan.sequence_id, layout, now_s)
        images, index = [], 0
        for steps in layout.steps:
            images.append(tuple(scan.frames[index + n].image for n in range(steps)))  # N_e frames (H, W)
            index += steps
        references = {kind: scan.frames[index + offset].image for offset, kind in enumerate(layout.references)}
        stamps = [f.stamp_ns for f in scan.frames.values()]
        del self._pending[scan.sequence_id]
        self._remember(scan.sequence_id, now_s, "completed")
        return AssembledScan(sequence_id=scan.sequence_id, layout=layout, images=tuple(images),
                             first_stamp_ns=min(stamps), last_stamp_ns=max(stamps),
                             first_arrival_s=scan.first_arrival_s, references=references)

    def _layout_from_triggers(self, scan: _Pending):
        """ScanLayout of a complete trigger-laid scan, or the reason it is inconsistent."""
        groups: dict[int, FrameInfo] = {}   # first pattern_index of each entry -> a frame of it
        references = sorted((f.pattern_index, f.kind) for f in scan.frames.values() if f.kind in REFERENCE_KINDS)
        for frame in scan.frames.values():
            if frame.kind not in REFERENCE_KINDS:
                groups.setdefault(frame.pattern_index - frame.step, frame)
        starts = sorted(groups)
        index = 0
        for start in starts:
            if start != index:
                return (f"out of order: an entry starts at pattern {start} but the entries before it end at "
                        f"pattern {index}")
            index += groups[start].steps
        if [i for i, _ in references] != list(range(index, index + len(references))):
            return "out of order: the reference frames (white, black) must follow the fringe sets"
        index += len(references)
        if index != scan.pattern_count:
            return f"out of order: the entries cover {index} patterns; pattern_count is {scan.pattern_count}"
        return ScanLayout(frequencies=tuple(groups[s].frequency for s in starts),
                          steps=tuple(groups[s].steps for s in starts),
                          references=tuple(kind for _, kind in references), **self._geometry)

    def _missing(self, scan: _Pending) -> str:
        missing = [i for i in range(scan.pattern_count) if i not in scan.frames]
        shown = []
        for index in missing[:6]:
            if scan.layout is not None and scan.layout.reference_at(index) is not None:
                shown.append(f"{index} ({scan.layout.reference_at(index)})")
            elif scan.layout is not None:
                entry, step = scan.layout.locate(index)
                shown.append(f"{index} (f={scan.layout.frequencies[entry]:g} step {step})")
            else:
                shown.append(str(index))
        more = f" and {len(missing) - 6} more" if len(missing) > 6 else ""
        return "pattern " + ", ".join(shown) + more if missing else "nothing"
