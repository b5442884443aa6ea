"""Subscribers that keep what they get, as a robot's consumers do (a SLAM front end's window of clouds, a map
accumulator, a recorder behind its writes), and subscribers that cannot map: what the publisher's shared memory
then costs, and what it says.

The publisher is a real process (``tests/graph/nodes/shm_limited_publisher.py``, 100 kB images); the keeping
subscriber is this process or another real one.
"""

from __future__ import annotations

import collections
import mmap
import time
from pathlib import Path

import numpy as np

from dptpu.graph import Node, SingleThreadedExecutor
from dptpu.graph.segment_pool import SegmentPool
from dptpu.graph.shared_memory import HEADER_BYTES, SharedMemoryConfig
from dptpu.messages import Image

from .nodes.shm_limited_publisher import SHAPE, TOPIC
from .nodes.shm_peer import is_shared
from .test_shared_memory_limits import _intact, _keep_everything


def _segment_bytes(nbytes: int) -> int:
    """The size of the segment a pool makes for one array of ``nbytes`` (header, 1/16 room, whole pages)."""
    need = HEADER_BYTES + (nbytes + 63) // 64 * 64
    return (need + need // 16 + mmap.PAGESIZE - 1) // mmap.PAGESIZE * mmap.PAGESIZE


def test_a_subscriber_that_keeps_every_message_holds_the_pool_at_its_bytes_and_nothing_is_lost(context, spawn):
    # a subscriber that keeps every message holds every segment: the pool grows to DPTPU_SHM_POOL_MB and no
    # further (the publisher's memory stays bounded whatever the subscriber keeps), says so in one line, and sends
    # the rest through ZeroMQ, every message intact
    count, pool_mb = 40, 1
    publisher = spawn("shm_limited_publisher", "--count", str(count), "--period", "0.005",
                      env={"DPTPU_SHM_POOL_MB": str(pool_mb)})
    kept = _keep_everything(context, count, publisher)
    report = publisher.wait_event("published", timeout=30.0)
    assert report["errors"] == []
    assert sorted(_intact(kept)) == list(range(count))
    most = (pool_mb << 20) // _segment_bytes(int(np.prod(SHAPE)))  # 9 segments of 108 KiB in 1 MiB
    assert report["segments"] == most and report["shared"] == most  # none let go: none reused
    assert report["pool_bytes"] == most * _segment_bytes(int(np.prod(SHAPE))) <= pool_mb << 20
    assert report["full"] == count - most
    assert sum(is_shared(msg.data) for msg in kept) == most
    assert publisher.wait_for_stderr("DPTPU_SHM_POOL_MB"), publisher.stderr
    assert publisher.stderr.count("shared memory of dptpu:limits:image") == 1  # one line, not one a message


def test_a_subscriber_that_keeps_the_last_messages_holds_that_many_segments_and_no_more(context, spawn):
    # a SLAM front end's window: the last N messages kept. The pool grows to what the subscriber can hold (N kept,
    # its queue, the one being written) and reuses those segments from then on: every message through shared memory
    count, window, depth = 60, 5, 10
    publisher = spawn("shm_limited_publisher", "--count", str(count), "--period", "0.01")
    kept: collections.deque = collections.deque(maxlen=window)
    indices: list[int] = []
    node = Node("window_keeper", context=context)
    subscription = node.create_subscription(
        Image, TOPIC, lambda msg: (kept.append(msg), indices.append(int(msg.header.frame_id))), depth)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    publisher.wait_event("ready", timeout=30.0)
    deadline = time.monotonic() + 60.0
    while len(indices) < count and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    report = publisher.wait_event("published", timeout=30.0)
    # in order, none changed; under load the subscription's queue (KEEP_LAST 10) may drop some, each counted
    assert indices == sorted(set(indices)) and indices[-1] == count - 1
    assert len(indices) + subscription.queue_dropped_count + subscription.dropped_count == count
    assert subscription.lost_count == 0  # no descriptor came to a segment written again
    assert _intact(list(kept)) == indices[-window:]
    assert report["shared"] == count and report["full"] == 0
    assert report["segments"] <= window + depth + 2, report  # held: kept, queued, and the one being written
    assert report["pool_bytes"] == report["segments"] * _segment_bytes(int(np.prod(SHAPE)))


def test_a_subscriber_that_cannot_map_is_named_once_by_the_publisher(context, spawn):
    # one subscriber that takes no shared memory (DPTPU_SHM=off here; a remote topic echo over tcp alike) sends
    # every subscriber of the topic back to ZeroMQ copies: the publisher says so once, naming the topic and it
    count = 6
    other = spawn("shm_limited_subscriber", "--count", str(count), env={"DPTPU_SHM": "off"})
    other.wait_event("ready", timeout=20.0)
    publisher = spawn("shm_limited_publisher", "--count", str(count), "--period", "0.05", "--wait-subs", "2")
    kept = _keep_everything(context, count, publisher)
    report = publisher.wait_event("published", timeout=30.0)
    assert sorted(_intact(kept)) == list(range(count))
    assert report["shared"] == 0 and not any(is_shared(msg.data) for msg in kept)
    done = other.wait_event("done", timeout=30.0)
    assert done["intact"] == count
    assert publisher.wait_for_stderr("cannot map"), publisher.stderr
    lines = [line for line in publisher.stderr.splitlines() if "cannot map" in line]
    assert len(lines) == 1, publisher.stderr
    assert "/limits/image" in lines[0] and "/limited_subscriber" in lines[0], lines[0]


def _resident_shmem_bytes() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("RssShmem:"):
            return int(line.split()[1]) * 1024
    raise AssertionError("no RssShmem in /proc/self/status")


def test_a_new_segment_is_resident_before_its_writer_touches_it():
    # a segment made while subscribers hold the others is filled at once (the cloud node's cv2.merge into a
    # loan): its pages are allocated in one pass at its making (MAP_POPULATE), not faulted in one by one by the fill
    pool = SegmentPool(SharedMemoryConfig(key=b"test"), "test:populate")
    try:
        before = _resident_shmem_bytes()
        segment, entries = pool.loan([8 << 20])
        grown = _resident_shmem_bytes() - before
        assert segment.size >= 8 << 20
        assert grown >= segment.size - mmap.PAGESIZE, (grown, segment.size)  # every page but the header's
        pool.cancel_loan(segment)
    finally:
        pool.close()


def test_a_pool_closes_free_segments_idle_for_its_idle_time_and_keeps_the_others():
    # DPTPU_SHM_IDLE_S: a robot that scans every 12 s keeps its segments with a minute (no new pages a scan); the
    # pool still closes what has been idle for longer
    config = SharedMemoryConfig.from_environment({"DPTPU_SHM_IDLE_S": "0.2"})
    assert config is not None and config.idle_s == 0.2
    kept = SegmentPool(SharedMemoryConfig(key=b"test", idle_s=60.0), "test:kept")
    closing = SegmentPool(config, "test:closing")
    try:
        for pool in (kept, closing):
            assert pool.write([memoryview(bytes(100_000))], readers=0) is not None
        time.sleep(1.2)  # past the idle time and the pools' once-a-second trim
        for pool in (kept, closing):
            assert pool.write([memoryview(bytes(300_000))], readers=0) is not None  # another size: a new segment
        assert kept.segment_count == 2  # the first one kept: written 1.2 s ago, idle for less than 60 s
        assert closing.segment_count == 1  # the first one closed: idle for more than 0.2 s
    finally:
        kept.close()
        closing.close()


def test_a_segment_lent_and_let_go_unpublished_is_kept_for_its_idle_time():
    # a camera node lets go of a frame no Trigger claimed: its segment, never written, is free and not idle since
    # ever (the trim a second after its making closed it, and the next loan made a new one: the fresh-clone CI's
    # test_a_loan_let_go_unpublished_goes_back_to_the_pool under load)
    pool = SegmentPool(SharedMemoryConfig(key=b"test", idle_s=60.0), "test:lent")
    try:
        segment, _ = pool.loan([100_000])
        pool.cancel_loan(segment)
        time.sleep(1.1)  # past the pool's once-a-second trim
        again, _ = pool.loan([100_000])
        assert again is segment and pool.segment_count == 1
        pool.cancel_loan(again)
    finally:
        pool.close()
