"""The segments of the shared-memory path: generations, pickups and leases, locks of killed readers, strangers.

Readers here open the segments as a subscriber does (``/proc/<pid>/fd``: a file description of their own, so the
``flock`` rules hold between the pool and the reader even in one process); the killed reader and the stranger are
real processes.
"""

from __future__ import annotations

import fcntl
import gc
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from dptpu.graph import segment_pool, shared_memory
from dptpu.graph.segment_pool import SegmentPool
from dptpu.graph.shared_memory import SharedMemoryConfig, StaleSegmentError, read_message, unpack_descriptor

TOPIC = b"/t"
HEADER = b"header"


def _pool(lease_s: float = 5.0, pool_mb: float = 64) -> SegmentPool:
    return SegmentPool(SharedMemoryConfig(lease_s=lease_s, pool_bytes=int(pool_mb * (1 << 20)), key=b"k"), "dptpu:t")


def _payload(seed: int, nbytes: int = 300_000) -> list[memoryview]:
    rng = np.random.default_rng(seed)
    return [memoryview(rng.integers(0, 256, nbytes, dtype=np.uint8)), memoryview(rng.integers(0, 256, 1000,
                                                                                             dtype=np.uint8))]


def _read(descriptor: bytes) -> list:
    return read_message(TOPIC, HEADER, descriptor)[2:]


def test_message_reads_back_bit_exact_as_read_only_views():
    pool = _pool()
    try:
        arrays = _payload(1)
        views = _read(pool.write(arrays, readers=1))
        assert [bytes(v) for v in views] == [bytes(a) for a in arrays]
        assert all(v.readonly for v in views)
        assert all(np.frombuffer(v, np.uint8).ctypes.data % shared_memory.ALIGNMENT == 0 for v in views)
    finally:
        del views
        gc.collect()
        pool.close()


def test_generation_counter_refuses_a_recycled_segment():
    pool = _pool()
    try:
        first = pool.write(_payload(1), readers=0)  # nobody to wait for: the segment is free again at once
        second = pool.write(_payload(2), readers=0)
        assert pool.segment_count == 1  # the same segment, written again
        assert unpack_descriptor(second).generation == unpack_descriptor(first).generation + 1
        with pytest.raises(StaleSegmentError, match="generation 2.*descriptor generation 1"):
            _read(first)
        assert bytes(_read(second)[0]) == bytes(_payload(2)[0])
    finally:
        gc.collect()
        pool.close()


def test_a_held_message_is_never_written_again_and_its_segment_returns_when_let_go(monkeypatch):
    # no idle trim: on a loaded machine the writes below can outlast IDLE_S, and the let-go segment was closed
    monkeypatch.setattr(segment_pool, "IDLE_S", float("inf"))
    pool = _pool(lease_s=0.0)
    try:
        held = _read(pool.write(_payload(1), readers=1))
        for seed in range(2, 12):  # a slow subscriber holds the first: every later write takes another segment
            views = _read(pool.write(_payload(seed), readers=1))
            del views
            gc.collect()
        assert bytes(held[0]) == bytes(_payload(1)[0])  # untouched under the holder
        assert pool.segment_count == 2  # the held one and the one the others took in turn
        del held
        gc.collect()
        pool.write(_payload(20), readers=1)
        pool.write(_payload(21), readers=1)
        assert pool.segment_count == 2  # the let-go segment serves again
    finally:
        gc.collect()
        pool.close()


def test_segments_a_reader_holds_are_asked_about_once_a_round_not_at_every_write(monkeypatch):
    monkeypatch.setattr(segment_pool, "IDLE_S", float("inf"))
    pool = _pool(lease_s=0.0)
    try:
        held = [_read(pool.write(_payload(seed), readers=1)) for seed in range(24)]  # a scan's 24 frames, held
        done = [_read(pool.write(_payload(seed), readers=1)) for seed in range(24, 48)]  # the next 24, let go
        del done
        gc.collect()
        assert pool.segment_count == 48  # least recently written first: the held ones
        asked = []
        lock = segment_pool._Segment.lock  # lease 0: every segment looked at is asked for its lock
        monkeypatch.setattr(segment_pool._Segment, "lock", lambda self: asked.append(self) or lock(self))
        kept = [_read(pool.write(_payload(seed), readers=1)) for seed in range(48, 72)]  # the next scan, held too
        # the first write asked the 24 held ones, then took a free one; they went to the end with it, so the other
        # writes found free ones first (before: every write asked all 24 held ones again, 24 x 25 = 600 in all)
        assert pool.segment_count == 48 and len(asked) == 24 + 1 + 23
        assert [bytes(views[0]) for views in held] == [bytes(_payload(seed)[0]) for seed in range(24)]
        assert len(kept) == 24
    finally:
        held = kept = []
        gc.collect()
        pool.close()


class _CountingFcntl:
    """The ``fcntl`` module as the segment pool sees it, counting the locks it asks for."""

    def __init__(self):
        self.tries = 0

    def __getattr__(self, name):
        return getattr(fcntl, name)

    def flock(self, fd, operation):
        self.tries += operation != fcntl.LOCK_UN
        return fcntl.flock(fd, operation)


def test_a_writer_does_not_ask_the_lock_of_segments_whose_readers_hold_messages(monkeypatch):
    monkeypatch.setattr(segment_pool, "IDLE_S", float("inf"))
    pool = _pool(lease_s=60.0)
    counting = _CountingFcntl()
    try:
        held = [_read(pool.write(_payload(seed), readers=1)) for seed in range(24)]  # a scan's frames, held
        monkeypatch.setattr(segment_pool, "fcntl", counting)
        pool.write(_payload(24), readers=0)
        assert pool.segment_count == 25 and counting.tries == 1  # the new segment's own lock: no held one asked
        del held[:12]  # the reader lets go of half: it counts each let-go in the header
        gc.collect()
        counting.tries = 0
        for seed in range(25, 37):
            pool.write(_payload(seed), readers=0)
        assert pool.segment_count == 25  # the let-go ones (and the unread one) served again
        assert counting.tries <= 13  # each write one lock that is granted, plus at most one refused
    finally:
        held.clear()
        gc.collect()
        pool.close()


def test_a_descriptor_not_yet_picked_up_keeps_its_segment_until_the_lease():
    pool = _pool(lease_s=0.3)
    try:
        pending = pool.write(_payload(1), readers=1)
        pool.write(_payload(2), readers=1)
        assert pool.segment_count == 2  # the first still waits for its subscriber
        assert bytes(_read(pending)[0]) == bytes(_payload(1)[0])  # and it gets it, intact
        gc.collect()
        time.sleep(0.35)  # the second's lease passes (never picked up: dropped in transport, say)
        pool.write(_payload(3), readers=1)
        pool.write(_payload(4), readers=1)
        assert pool.segment_count == 2
    finally:
        gc.collect()
        pool.close()


def test_full_pool_says_no_and_the_publisher_falls_back():
    pool = _pool(lease_s=60.0, pool_mb=1)
    try:
        assert pool.write(_payload(1), readers=1) is not None
        assert pool.write(_payload(2), readers=1) is not None
        assert pool.write(_payload(3), readers=1) is not None
        assert pool.write(_payload(4), readers=1) is None  # 4 x 300 kB > 1 MiB, none picked up
        assert pool.full_count == 1 and pool.pool_bytes <= 1 << 20
    finally:
        pool.close()


_HOLDER = """
import sys, time
from dptpu.graph.shared_memory import read_message
views = read_message(b"/t", b"h", bytes.fromhex(sys.argv[1]))
print("holding", flush=True)
time.sleep(60)
"""


def test_a_killed_reader_releases_its_segment():
    pool = _pool(lease_s=0.0)
    reader = None
    try:
        descriptor = pool.write(_payload(1), readers=1)
        reader = subprocess.Popen([sys.executable, "-c", _HOLDER, descriptor.hex()], stdout=subprocess.PIPE, text=True)
        assert reader.stdout.readline().strip() == "holding"
        pool.write(_payload(2), readers=0)
        assert pool.segment_count == 2  # the reader holds the first
        os.kill(reader.pid, signal.SIGKILL)
        reader.wait(timeout=10)
        pool.write(_payload(3), readers=0)
        pool.write(_payload(4), readers=0)
        assert pool.segment_count == 2  # the kernel dropped the killed reader's lock: both serve again
    finally:
        if reader is not None and reader.poll() is None:
            reader.kill()
            reader.wait()
        pool.close()


_STRANGER = """
import os, sys
os.setgid(65534)
os.setuid(65534)
try:
    os.open(sys.argv[1], os.O_RDONLY)
except PermissionError:
    print("refused")
else:
    print("opened")
"""


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to run a process as another user (nobody)")
def test_a_stranger_cannot_open_a_segment():
    pool = _pool()
    try:
        descriptor = unpack_descriptor(pool.write(_payload(1), readers=0))
        path = f"/proc/{os.getpid()}/fd/{descriptor.fd}"
        assert os.stat(path).st_mode & 0o777 == 0o600
        assert not any(name.startswith("dptpu") for name in os.listdir("/dev/shm"))  # no name anywhere
        stranger = subprocess.run([sys.executable, "-c", _STRANGER, path], capture_output=True, text=True, timeout=30)
        assert stranger.stdout.strip() == "refused", stranger.stderr
    finally:
        pool.close()


def test_a_forged_descriptor_is_refused_without_blocking(tmp_path):
    from dptpu.graph.shared_memory import SharedMemoryError, pack_descriptor

    regular = tmp_path / "file"
    regular.write_bytes(bytes(4096))
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    fds = [os.open(regular, os.O_RDONLY), os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)]
    try:
        for fd in fds:
            inode = os.fstat(fd).st_ino
            forged = pack_descriptor(os.getpid(), fd, inode, bytes(16), 1, 4096, [(64, 100)])
            started = time.monotonic()
            with pytest.raises(SharedMemoryError, match="is not the segment the descriptor names"):
                read_message(TOPIC, HEADER, forged)
            assert time.monotonic() - started < 5.0  # a FIFO is opened without blocking
        gone = pack_descriptor(2**22 + 12345, 3, 1, bytes(16), 1, 4096, [(64, 100)])  # no such process
        with pytest.raises(SharedMemoryError, match="cannot open segment"):
            read_message(TOPIC, HEADER, gone)
        with pytest.raises(SharedMemoryError, match="names bytes 64..5000 of a segment of 4096"):
            read_message(TOPIC, HEADER, pack_descriptor(os.getpid(), fds[0], 1, bytes(16), 1, 4096, [(64, 4936)]))
    finally:
        for fd in fds:
            os.close(fd)
