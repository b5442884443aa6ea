"""Gathering a camera's frames into bursts: an entry's ``N`` phase-shifted frames in one message (issue 20).

A camera side (the sim node, the camera node) that publishes :class:`~dptpu.messages.FringeBurst` s hands each
frame with its Trigger to :class:`FrameBursts` as it comes; a burst is ready when its entry's last step is in (a
reference frame is a burst of one). Pure logic, time passed in, like the phase node's ``SequenceAssembler``:

- frames are copied once, into the burst's buffer (``allocate``: a loaned shared-memory segment where a loan pays);
- a frame of another scan or entry, a repeated or earlier step, or another size first sends the burst pending as
  it stands (fewer frames than its entry: the phase node then reports the scan incomplete, naming the missing
  patterns, as it does for single frames), so frames are never held back behind a lost one;
- ``due(now_s)`` sends a burst whose next frame has not come within its wait (a dropped Trigger): ``max_wait_s``, or
  twice the latest spacing of two frames of one scan where that is longer, so that a camera slower than
  ``1 / max_wait_s`` frames a second (a long exposure, the sim's ``frame_rate_hz``) still sends an entry as one burst
  (with a fixed wait each of its frames went alone, in a buffer of the whole entry).

Shared by every side that gathers or sends an entry at once: :func:`continues_entry` (the projector's TriggerBursts
too), :func:`loaned_buffer` and :func:`burst_message` (the sim and camera nodes).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from dptpu.messages import FringeBurst, Header, Time, Trigger
from dptpu.messages.scanner import REFERENCE_KINDS

__all__ = ["Burst", "FrameBursts", "burst_message", "continues_entry", "frames_in_entry", "loaned_buffer"]


def frames_in_entry(trigger: Trigger) -> int:
    """Frames of ``trigger``'s entry: 1 for a reference frame or an unknown step count, else its ``steps``."""
    if trigger.kind in REFERENCE_KINDS or trigger.steps < 1:
        return 1
    return int(trigger.steps)


def continues_entry(last: Trigger, trigger: Trigger) -> bool:
    """Whether ``trigger`` is a later pattern of ``last``'s entry: the same scan, a phase pattern of the same
    frequency and steps, the same first pattern (``pattern_index - step``), a later step (a repeated or lost one
    is not)."""
    return (trigger.sequence_id == last.sequence_id and trigger.kind == last.kind == "phase"
            and trigger.steps == last.steps and trigger.frequency == last.frequency
            and trigger.pattern_index - trigger.step == last.pattern_index - last.step and trigger.step > last.step)


def loaned_buffer(publisher, shape: tuple[int, ...], dtype) -> np.ndarray:
    """A burst's (N, H, W) buffer: lent by ``publisher`` where a loan pays (published without a copy), else a new
    array (which ZeroMQ sends without a copy)."""
    dtype = np.dtype(dtype)
    if not publisher.can_loan_messages(math.prod(shape) * dtype.itemsize):
        return np.empty(shape, dtype)
    (buffer,) = publisher.borrow_loaned_arrays([(shape, dtype)])
    return buffer


def burst_message(burst: Burst, frame_id: str) -> FringeBurst:
    """The FringeBurst of ``burst``: its frames (a view of its buffer), stamped with its last frame's stamp."""
    header = Header(stamp=Time.from_ns(burst.last_stamp_ns), frame_id=frame_id)
    return FringeBurst.from_frames(burst.frames, burst.triggers, header=header)


@dataclass
class Burst:
    """A burst ready to publish: ``frames`` (n, H, W), the first ``n`` of ``buffer`` (N, H, W), one Trigger each,
    and the stamp of the last frame (ns)."""

    buffer: np.ndarray
    triggers: list[Trigger] = field(default_factory=list)
    last_stamp_ns: int = 0
    last_added_s: float = 0.0

    @property
    def frames(self) -> np.ndarray:
        return self.buffer[:len(self.triggers)]

    @property
    def complete(self) -> bool:
        return len(self.triggers) == self.buffer.shape[0]


class FrameBursts:
    """Frames with their Triggers in, :class:`Burst` s out (see the module docstring).

    Parameters
    ----------
    allocate : callable ``(shape, dtype) -> ndarray``
        The buffer of a new burst, (N, H, W) of the frames' dtype; a loaned segment where the publisher lends one.
    max_wait_s : float
        Shortest wait for a burst's next frame before :meth:`due` sends it as it stands (:attr:`wait_s`).
    """

    def __init__(self, allocate: Callable[[tuple[int, ...], np.dtype], np.ndarray], *, max_wait_s: float = 0.5):
        if not max_wait_s > 0:
            raise ValueError(f"max_wait_s must be > 0 seconds; got {max_wait_s}")
        self._allocate = allocate
        self.max_wait_s = float(max_wait_s)
        self._pending: Burst | None = None
        self._last_frame: tuple[int, float] | None = None  # (sequence_id, now_s) of the latest frame added
        self.frame_spacing_s = 0.0  # the latest spacing of two consecutive frames of one scan (s)

    @property
    def wait_s(self) -> float:
        """The wait for a burst's next frame: ``max_wait_s``, or twice :attr:`frame_spacing_s` where longer."""
        return max(self.max_wait_s, 2.0 * self.frame_spacing_s)

    @property
    def pending(self) -> Burst | None:
        """The burst being filled (None when none)."""
        return self._pending

    def add(self, trigger: Trigger, frame: np.ndarray, stamp_ns: int, now_s: float) -> list[Burst]:
        """Copy ``frame`` (H, W) into its burst; the bursts it makes ready (the one pending before it, cut short
        because ``frame`` cannot join it, and its own once complete), in order."""
        if frame.ndim != 2:
            raise ValueError(f"a burst's frame must be (H, W); got shape {frame.shape}")
        if self._last_frame is not None and self._last_frame[0] == trigger.sequence_id:
            self.frame_spacing_s = max(0.0, now_s - self._last_frame[1])
        self._last_frame = (trigger.sequence_id, now_s)
        ready = []
        pending = self._pending
        if pending is not None and not self._joins(pending, trigger, frame):
            ready.append(pending)
            pending = self._pending = None
        if pending is None:
            count = frames_in_entry(trigger)
            pending = self._pending = Burst(self._allocate((count, *frame.shape), frame.dtype))
        row = pending.buffer[len(pending.triggers)]
        if row.ctypes.data != frame.ctypes.data:  # a camera may have copied the frame into its row already
            np.copyto(row, frame)
        pending.triggers.append(trigger)
        pending.last_stamp_ns = int(stamp_ns)
        pending.last_added_s = now_s
        if pending.complete:
            ready.append(pending)
            self._pending = None
        return ready

    def due(self, now_s: float) -> list[Burst]:
        """The pending burst, when its next frame is :attr:`wait_s` late (sent as it stands)."""
        if self._pending is None or now_s - self._pending.last_added_s < self.wait_s:
            return []
        return self.flush()

    def flush(self) -> list[Burst]:
        """The pending burst as it stands, if any."""
        pending, self._pending = self._pending, None
        return [] if pending is None else [pending]

    @staticmethod
    def _joins(pending: Burst, trigger: Trigger, frame: np.ndarray) -> bool:
        """Whether ``frame`` is the next frame of ``pending``'s entry: same scan and entry, the next pattern, the
        same size and dtype."""
        return (continues_entry(pending.triggers[-1], trigger) and len(pending.triggers) < pending.buffer.shape[0]
                and frame.shape == pending.buffer.shape[1:] and frame.dtype == pending.buffer.dtype)
