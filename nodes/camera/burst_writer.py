"""The camera node's frame bursts: each frame copied once, out of the producer's buffer into its burst (issue 20).

With ``frame_bursts:=true`` the camera node publishes an entry's ``N`` frames as one
:class:`~dptpu.messages.FringeBurst` (gathered by :class:`~dptpu.nodes.frame_bursts.FrameBursts`) instead of ``N``
FringeFrames. The acquisition asks for a frame's destination (:meth:`BurstWriter.row`) once the frame is in and the
Trigger it pairs with is known, before copying it out of the producer's buffer: the destination is the frame's row of
its burst (a segment loaned by the bursts' publisher where a loan pays), so that the gatherer's copy is a copy onto
itself, which numpy skips, and the frame is copied once, as a single FringeFrame is.

The row is foreseen, not decided: a frame goes to the pending burst's next row when that burst has its size, else to
row 0 of a new burst's buffer, made here and handed to the gatherer when it asks for one. Where the gatherer decides
otherwise (a frame of a new entry after a lost one: the pending burst is sent short), it copies the frame from the
foreseen row into the right one; a frame copied before its Trigger came (hardware triggering, the frame first) is
copied into its row then. :attr:`BurstWriter.frames_copied_twice` counts both.

Threads: the acquisition thread calls :meth:`row` and :meth:`add`, the node's timer :meth:`publish_due`; one lock
keeps the gatherer's state, and a burst whose row is being filled is not sent by the timer meanwhile.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from dptpu.messages import Trigger
from dptpu.nodes.frame_bursts import Burst, FrameBursts, burst_message, frames_in_entry, loaned_buffer

__all__ = ["BurstWriter"]


class BurstWriter:
    """Frames with their Triggers in, :class:`~dptpu.messages.FringeBurst` s published (module docstring).

    Parameters
    ----------
    publisher
        The bursts' publisher (``/camera/frame_bursts``); it lends the bursts' buffers where a loan pays.
    frame_id : callable () -> str
        ``header.frame_id`` of the next burst (settable at run time).
    max_wait_s : float
        Longest wait for a burst's next frame before :meth:`publish_due` sends it as it stands (a lost Trigger).
    """

    def __init__(self, publisher, frame_id: Callable[[], str], *, max_wait_s: float = 0.5):
        self.publisher = publisher
        self._frame_id = frame_id
        self._lock = threading.Lock()
        self._bursts = FrameBursts(self._buffer, max_wait_s=max_wait_s)
        self._prepared: np.ndarray | None = None  # a new burst's buffer, its row 0 given to a frame being copied
        self._filling_since: float | None = None  # a row is being filled (monotonic s); the timer leaves it be
        self.bursts_published = 0
        self.frames_copied_twice = 0

    @property
    def max_wait_s(self) -> float:
        return self._bursts.max_wait_s

    def row(self, trigger: Trigger, shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        """Acquisition thread: where the frame of ``trigger`` is copied out of the producer's buffer."""
        with self._lock:
            self._filling_since = time.monotonic()
            pending = self._bursts.pending
            if pending is not None and pending.buffer.shape[1:] == tuple(shape) and pending.buffer.dtype == dtype:
                return pending.buffer[len(pending.triggers)]
            self._prepared = loaned_buffer(self.publisher, (frames_in_entry(trigger), *shape), np.dtype(dtype))
            return self._prepared[0]

    def add(self, trigger: Trigger, frame: np.ndarray, stamp_ns: int) -> None:
        """Acquisition thread: ``frame`` (H, W) of ``trigger`` joins its burst; the bursts it completes are sent."""
        with self._lock:
            ready = self._bursts.add(trigger, frame, stamp_ns, time.monotonic())
            self._filling_since = None
            self._prepared = None
            holder = ready[-1] if ready and ready[-1].triggers[-1] is trigger else self._bursts.pending
            if holder is None or not _same_memory(holder.frames[-1], frame):
                self.frames_copied_twice += 1
            for burst in ready:
                self._publish(burst)

    def publish_due(self) -> None:
        """Timer: send the pending burst when its next frame is ``max_wait_s`` late (not while a row is filled)."""
        with self._lock:
            now_s = time.monotonic()
            if self._filling_since is not None and now_s - self._filling_since < self.max_wait_s:
                return
            for burst in self._bursts.due(now_s):
                self._publish(burst)

    def flush(self) -> None:
        """Send the pending burst as it stands (the node is closing)."""
        with self._lock:
            for burst in self._bursts.flush():
                self._publish(burst)

    # --- helpers (holding the lock) ----------------------------------------------------------------

    def _buffer(self, shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        """The gatherer's ``allocate``: the buffer prepared by :meth:`row` when it fits, else a new one."""
        prepared, self._prepared = self._prepared, None
        if prepared is not None and prepared.shape == tuple(shape) and prepared.dtype == dtype:
            return prepared
        return loaned_buffer(self.publisher, shape, dtype)

    def _publish(self, burst: Burst) -> None:
        self.publisher.publish(burst_message(burst, self._frame_id()))
        self.bursts_published += 1


def _same_memory(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether ``a`` and ``b`` are the same pixels in memory (not equal values: the same bytes)."""
    return (a.__array_interface__["data"][0] == b.__array_interface__["data"][0] and a.shape == b.shape
            and a.strides == b.strides)
