"""A publisher's pool of shared-memory segments (the writing side of :mod:`.shared_memory`).

Each segment is an anonymous memfd of this process (mode 0600, sealed against resizing), mapped read-write here
and read-only by the subscribers, who open it through ``/proc/<pid>/fd``. :meth:`SegmentPool.write` copies a
message's arrays into a free segment under an exclusive ``flock`` and returns the descriptor to send; a segment is
free when no subscriber holds its shared lock and either every subscriber the descriptor went to picked it up or
the lease has passed (:mod:`.shared_memory`). The pool takes the first free segment that fits in the order of the last
write or the last time it was found busy, makes a new one while the pool stays within its bytes, and otherwise
says no (the publisher sends through ZeroMQ).
Segments idle for :data:`IDLE_S` (``DPTPU_SHM_IDLE_S``) are closed.

The pool also says no, with one log line a pool and reason, where a new segment would not serve or cannot be made:

- the process is not *dumpable* (it changed its user or group, e.g. started as root and dropped privileges, runs a
  binary with file capabilities, or called ``prctl(PR_SET_DUMPABLE, 0)``): the kernel then lets no other process of
  its user open its ``/proc/<pid>/fd``, so no subscriber could map a segment;
- the process holds :data:`~.shared_memory.FD_SHARE` of its file-descriptor limit (``ulimit -n``) already: each
  segment costs two descriptors (the memfd and the duplicate Python's ``mmap`` keeps), and a subscriber that keeps
  every message would otherwise grow the pool until ``publish`` failed with ``EMFILE`` and the process could open
  no socket or file;
- making it fails (``memfd_create``, ``ftruncate`` or ``mmap`` raise ``OSError``: no descriptor, no memory);
- the pool is at its bytes (``DPTPU_SHM_POOL_MB``) and every segment is held: a subscriber that keeps every message
  (a map accumulator, a recorder far behind) holds at most that much of the publisher's memory, and gets the rest
  through ZeroMQ.

A new segment's pages are allocated when it is made (``MAP_POPULATE``), in one pass, not faulted in one by one by its
first write. And a publisher whose subscribers are not all able to map its segments sends through ZeroMQ: the pool
says so once, naming them (:meth:`SegmentPool.note_unmappable`).
"""

from __future__ import annotations

import ctypes
import fcntl
import mmap
import os
import resource
import time

import numpy as np

from .logging import get_logger
from .shared_memory import (
    ALIGNMENT,
    FD_SHARE,
    GENERATION_OFFSET,
    HEADER_BYTES,
    PICKUPS_OFFSET,
    RELEASES_OFFSET,
    SEALS,
    SEGMENT_MAGIC,
    SharedMemoryConfig,
    descriptor_room,
    own_segments,
    pack_descriptor,
    unmappable_subscribers,
)

__all__ = ["SegmentPool", "IDLE_S", "FD_SHARE", "UNMAPPABLE_WAIT_S", "process_dumpable"]

#: Seconds after its last write when a free segment is closed (``DPTPU_SHM_IDLE_S``): longer than a robot's pause
#: between two scans (it moves the scanner), whose next scan would otherwise make every segment of the graph again
#: (docs/benchmarks.md, "Consumers that keep clouds": a scan every 11 s, 10 s against 60 s).
IDLE_S = 60.0
#: Seconds :meth:`SegmentPool.note_unmappable` waits for the graph's announcements to name a subscriber that cannot
#: map before it logs without a name.
UNMAPPABLE_WAIT_S = 2.0
#: The header's pickup and let-go counters: their indices among its 8-byte words.
_PICKUPS_WORD = PICKUPS_OFFSET // 8
_RELEASES_WORD = RELEASES_OFFSET // 8
_PAGE = mmap.PAGESIZE
_POPULATE = getattr(mmap, "MAP_POPULATE", 0)  # Linux


def _aligned(nbytes: int) -> int:
    return (nbytes + ALIGNMENT - 1) // ALIGNMENT * ALIGNMENT


_PR_GET_DUMPABLE = 3
_libc: list = []


def process_dumpable() -> bool:
    """Whether the kernel lets other processes of this user open this one's ``/proc/<pid>/fd`` (``PR_GET_DUMPABLE``
    is 1); True where it cannot be asked."""
    if not _libc:
        try:
            _libc.append(ctypes.CDLL(None, use_errno=True).prctl)
        except (OSError, AttributeError):
            _libc.append(None)
    prctl = _libc[0]
    return prctl is None or prctl(_PR_GET_DUMPABLE, 0, 0, 0, 0) == 1


class _Segment:
    """One memfd segment: its descriptor, read-write map, identity and the state of its last write."""

    __slots__ = ("fd", "view", "array", "header", "size", "inode", "token", "generation", "readers", "written_at",
                 "loaned")

    def __init__(self, size: int, label: str):
        self.fd = os.memfd_create(label, os.MFD_CLOEXEC | os.MFD_ALLOW_SEALING)
        try:
            os.fchmod(self.fd, 0o600)
            os.ftruncate(self.fd, size)
            # its size is fixed for good: nobody (a process of this user that opens /proc/<pid>/fd) can shrink it
            # under a mapping, which would kill the publisher and every reader with SIGBUS at their next access
            fcntl.fcntl(self.fd, fcntl.F_ADD_SEALS, SEALS)
            # every page allocated and mapped in one pass (MAP_POPULATE) rather than faulted in one at a time by the
            # writer's first pass: a segment is made when subscribers hold the others (they keep messages), and its
            # writer fills it at once (docs/benchmarks.md, "Consumers that keep clouds")
            self.view = mmap.mmap(self.fd, size, flags=mmap.MAP_SHARED | _POPULATE)
        except BaseException:
            os.close(self.fd)
            raise
        self.array = np.frombuffer(self.view, dtype=np.uint8)  # (size,) writable
        self.header = np.frombuffer(self.view, dtype="<u8", count=HEADER_BYTES // 8)  # (8,) the header's words
        self.size = size
        self.inode = os.fstat(self.fd).st_ino
        self.token = os.urandom(16)
        self.generation = 0
        self.readers = 0
        # its idle time counts from its making until its first write: a segment lent to a writer that let it go
        # unpublished is not closed by the next trim as idle since ever (made again at the next loan)
        self.written_at = time.monotonic()
        self.loaned = False  # lent to a writer that fills it in place (exclusively locked until it is published)
        self.view[:8] = SEGMENT_MAGIC
        self.view[8:24] = self.token
        own_segments[0] += 1

    def pickups(self) -> int:
        return int.from_bytes(self.view[PICKUPS_OFFSET:PICKUPS_OFFSET + 8], "little")

    def releases(self) -> int:
        return int.from_bytes(self.view[RELEASES_OFFSET:RELEASES_OFFSET + 8], "little")

    def free(self, now: float, lease_s: float) -> bool:
        """No descriptor of it is pending (picked up by all, or the lease passed) and no reader holds it: then
        this holds its exclusive lock (let go by :meth:`unlock`). Within the lease, a segment whose readers have
        let go of fewer messages than they picked up is busy without asking the lock (the let-go count is a hint;
        the lock decides)."""
        if self.loaned or self.held(now, lease_s):
            return False
        return self.lock()

    def held(self, now: float, lease_s: float) -> bool:
        """Within the lease, whether a reader has not picked it up yet or not let go (the header's counters: a
        hint, no system call)."""
        if now - self.written_at >= lease_s:
            return False
        header = self.header
        pickups = header[_PICKUPS_WORD]
        return self.readers > pickups or header[_RELEASES_WORD] < pickups

    def lock(self) -> bool:
        """Take its exclusive lock if no reader holds the shared one (one ``flock`` call)."""
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False  # a subscriber still holds an array of its last message
        return True

    def unlock(self) -> None:
        fcntl.flock(self.fd, fcntl.LOCK_UN)

    def close(self) -> None:
        del self.array, self.header
        try:
            self.view.close()
        except BufferError:
            pass  # a writer still holds a loaned array of it: the map goes with the last such array
        os.close(self.fd)
        own_segments[0] -= 1


class SegmentPool:
    """The segments of one publisher.

    Parameters
    ----------
    config : SharedMemoryConfig
        Its ``pool_bytes`` and ``lease_s``.
    label : str
        A name for the segments (shown in ``/proc/<pid>/maps`` as ``memfd:<label>``).

    Attributes
    ----------
    written_count : int
        Messages written into segments.
    full_count : int
        Messages refused because every segment was busy and no new one could be made: the pool at its bytes, at its
        share of the file-descriptor limit, the process not dumpable, or the kernel refusing a segment (sent through
        ZeroMQ).
    """

    def __init__(self, config: SharedMemoryConfig, label: str):
        self._config = config
        self._label = label[:200]
        self._segments: list[_Segment] = []  # least recently written (or found busy) first
        self._bytes = 0
        self._next_trim = 0.0
        self._reported: set[str] = set()  # reasons already logged (once a pool each)
        self._unmappable_since = self._unmappable_seen = float("-inf")  # note_unmappable's run of messages
        self.written_count = 0
        self.full_count = 0

    @property
    def segment_count(self) -> int:
        return len(self._segments)

    @property
    def pool_bytes(self) -> int:
        return self._bytes

    def write(self, arrays, readers: int) -> bytes | None:
        """Copy ``arrays`` (1-D uint8 memoryviews) into a free segment; the descriptor, or None when the pool is
        full (then send the message through ZeroMQ).

        ``readers`` is how many subscriptions the descriptor goes to (each counts its pickup in the segment).
        """
        sizes = [view.nbytes for view in arrays]
        need = HEADER_BYTES + sum(_aligned(n) for n in sizes)
        now = time.monotonic()
        segment = self._take(need, now)
        if segment is None:
            self.full_count += 1
            return None
        try:
            entries = []
            offset = HEADER_BYTES
            target = segment.array
            for view, nbytes in zip(arrays, sizes):
                target[offset:offset + nbytes] = np.frombuffer(view, dtype=np.uint8)
                entries.append((offset, nbytes))
                offset += _aligned(nbytes)
            segment.generation += 1
            segment.view[GENERATION_OFFSET:GENERATION_OFFSET + 8] = segment.generation.to_bytes(8, "little")
            segment.view[PICKUPS_OFFSET:PICKUPS_OFFSET + 8] = bytes(8)
            segment.view[RELEASES_OFFSET:RELEASES_OFFSET + 8] = bytes(8)
            segment.readers = readers
            segment.written_at = now
        finally:
            segment.unlock()
        self.written_count += 1
        return pack_descriptor(os.getpid(), segment.fd, segment.inode, segment.token, segment.generation,
                               segment.size, entries)

    def loan(self, sizes) -> tuple | None:
        """A free segment for arrays of ``sizes`` bytes, held for a writer that fills it in place: ``(segment,
        entries)`` with each array's ``(offset, nbytes)``, or None when the pool is full. Then
        :meth:`publish_loan` or :meth:`cancel_loan`."""
        need = HEADER_BYTES + sum(_aligned(n) for n in sizes)
        segment = self._take(need, time.monotonic())
        if segment is None:
            return None  # counted in full_count by the write of the plain arrays the writer gets instead
        segment.loaned = True
        entries, offset = [], HEADER_BYTES
        for nbytes in sizes:
            entries.append((offset, nbytes))
            offset += _aligned(nbytes)
        return segment, entries

    def publish_loan(self, segment: _Segment, entries, readers: int) -> bytes:
        """The descriptor of a loaned segment the writer has filled (the arrays are not copied)."""
        segment.generation += 1
        segment.view[GENERATION_OFFSET:GENERATION_OFFSET + 8] = segment.generation.to_bytes(8, "little")
        segment.view[PICKUPS_OFFSET:PICKUPS_OFFSET + 8] = bytes(8)
        segment.view[RELEASES_OFFSET:RELEASES_OFFSET + 8] = bytes(8)
        segment.readers = readers
        segment.written_at = time.monotonic()
        segment.loaned = False
        segment.unlock()
        self.written_count += 1
        return pack_descriptor(os.getpid(), segment.fd, segment.inode, segment.token, segment.generation,
                               segment.size, entries)

    def cancel_loan(self, segment: _Segment) -> None:
        """Take back a loaned segment that was not published."""
        segment.loaned = False
        segment.unlock()

    def _take(self, need: int, now: float) -> _Segment | None:
        """A free segment of ``need`` to ``2 * need`` bytes, exclusively locked, moved to the end; or a new one.

        The segments looked at before it (busy, or of another size) go to the end with it, in their order: a reader
        that holds many messages (a node assembling a scan of 24 frames) is not asked about each of them again at
        every write (a ``flock`` call each), only once they have come round."""
        if now >= self._next_trim:
            self._trim(now)
        lease_s = self._config.lease_s
        segments = self._segments
        largest = 2 * need + _PAGE
        for index, segment in enumerate(segments):  # Segment.free with its cheap tests inline: many are busy
            if segment.loaned or not need <= segment.size <= largest:
                continue
            if now - segment.written_at < lease_s:
                header = segment.header
                pickups = header[_PICKUPS_WORD]
                if segment.readers > pickups or header[_RELEASES_WORD] < pickups:
                    continue
            if segment.lock():
                self._segments = [*segments[index + 1:], *segments[:index], segment]
                return segment
        size = (need + need // 16 + _PAGE - 1) // _PAGE * _PAGE  # some room for a message a little larger
        if self._bytes + size > self._config.pool_bytes:
            made = self._evict_for(size, now)
            if made is None:
                most = self._config.pool_bytes / (1 << 20)
                self._report("bytes", f"its {len(self._segments)} segments ({self._bytes / (1 << 20):.1f} MiB; "
                             f"DPTPU_SHM_POOL_MB={most:g} is its most) are all held by subscribers (one keeps its "
                             "messages, or queues many); sending through ZeroMQ while none is free (a copy to every "
                             "subscriber)")
            return made
        return self._new_segment(size)

    def _evict_for(self, size: int, now: float) -> _Segment | None:
        """Close free segments of other sizes until ``size`` fits in the pool; a new segment, or None."""
        for segment in list(self._segments):
            if self._bytes + size <= self._config.pool_bytes:
                break
            if segment.free(now, self._config.lease_s):
                self._segments.remove(segment)
                self._bytes -= segment.size
                segment.close()
        if self._bytes + size > self._config.pool_bytes:
            return None
        return self._new_segment(size)

    def _new_segment(self, size: int) -> _Segment | None:
        """A new segment of ``size`` bytes, exclusively locked and listed; None (logged once a pool and reason) when
        no subscriber could open it, the process is at its share of descriptors, or the kernel refuses one."""
        if not process_dumpable():
            self._report("not dumpable", "this process is not dumpable (it changed its user or group, runs a binary "
                         "with file capabilities, or called prctl(PR_SET_DUMPABLE, 0)), so the kernel lets no other "
                         "process open its segments; sending every message through ZeroMQ")
            return None
        used, allowed = descriptor_room(FD_SHARE)
        if used + 2 > allowed:
            self._report("descriptors", f"this process has {used} file descriptors open, the most segments may "
                         f"leave it ({FD_SHARE:g} of ulimit -n {resource.getrlimit(resource.RLIMIT_NOFILE)[0]}; "
                         "subscribers hold its segments: one keeps its messages, or queues many); sending through "
                         "ZeroMQ while no segment of the pool is free (raise ulimit -n to share more)")
            return None
        try:
            segment = _Segment(size, self._label)
        except OSError as exc:
            self._report("kernel", f"a segment of {size} bytes cannot be made ({exc.strerror or exc}); sending "
                         "through ZeroMQ while no segment of the pool is free")
            return None
        fcntl.flock(segment.fd, fcntl.LOCK_EX)  # a new file: nobody else holds it
        self._segments.append(segment)
        self._bytes += size
        return segment

    def note_unmappable(self, topic: str, readers: int, mappable: int, entries, host: str, boot_id: str) -> None:
        """Say once (one log line) that ``readers - mappable`` of the topic's ``readers`` subscribers cannot map this
        publisher's segments, so every subscriber gets its messages through ZeroMQ, naming them from the graph's
        ``entries`` (:func:`~.shared_memory.unmappable_subscribers`). Called at each message sent so; while the
        announcements name none (they may come after the subscription), the line waits up to
        :data:`UNMAPPABLE_WAIT_S` of such messages."""
        if "unmappable" in self._reported:
            return
        now = time.monotonic()
        if now - self._unmappable_seen > UNMAPPABLE_WAIT_S:  # the first such message (of a new run of them)
            self._unmappable_since = now
        self._unmappable_seen = now
        named = unmappable_subscribers(entries, topic, host, boot_id)
        if not named and now - self._unmappable_since < UNMAPPABLE_WAIT_S:
            return
        who = ", ".join(named) if named else ("one of this host that takes none (of another user or PID namespace, "
                                              "or one that gave it up)")
        self._report("unmappable", f"{readers - mappable} of the {readers} subscribers of {topic} cannot map this "
                     f"process's segments: {who}; sending every message of {topic} to every subscriber through "
                     "ZeroMQ (a copy each) while it is connected")

    def _report(self, reason: str, text: str) -> None:
        if reason not in self._reported:
            self._reported.add(reason)
            get_logger("dptpu.graph").warning(f"shared memory of {self._label}: {text}")

    def _trim(self, now: float) -> None:
        self._next_trim = now + 1.0
        idle_s = IDLE_S if self._config.idle_s is None else self._config.idle_s
        for segment in list(self._segments):
            if now - segment.written_at >= idle_s and segment.free(now, self._config.lease_s):
                self._segments.remove(segment)
                self._bytes -= segment.size
                segment.close()

    def close(self) -> None:
        """Close every segment (subscribers that still map one keep it until they let go)."""
        for segment in self._segments:
            segment.close()
        self._segments.clear()
        self._bytes = 0
