"""Large messages through shared memory between real processes (``tests/graph/nodes/shm_peer.py``).

Every large message type arrives bit for bit as read-only views of the publisher's segment; a subscriber that
cannot map (over tcp, or with ``DPTPU_SHM=off``) makes the publisher send through ZeroMQ; killing the publisher
(``kill -9``) leaves nothing behind: no file in ``/dev/shm``, and the subscriber unmaps its segments.
"""

from __future__ import annotations

import gc
import os
import signal
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
import zmq

from dptpu.graph import Node, SingleThreadedExecutor, String, shared_memory
from dptpu.graph.shared_memory import host_key, pack_descriptor, shm_topic
from dptpu.graph.subscription import SHM_GIVE_UP
from dptpu.graph.transport import pack_envelope
from dptpu.messages import Image, encode

from .nodes.shm_peer import first_array, is_shared, large_messages, round_of, same_message
from .test_robustness_processes import _announce_raw_publisher

TOPICS = list(large_messages(0))


def _subscribe_all(context, received: list) -> SingleThreadedExecutor:
    node = Node("shm_test_sub", context=context)
    for topic, msg in large_messages(0).items():
        node.create_subscription(type(msg), topic, lambda m, t=topic: received.append((t, m)), 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    return executor


def _spin_until(executor, condition, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


def _check(received, *, shared: bool) -> None:
    expected = {}
    for topic, msg in received:
        index = round_of(msg)
        expected.setdefault(index, large_messages(index))
        assert same_message(topic, expected[index][topic], msg), topic
        array = first_array(msg)
        assert not array.flags.writeable
        assert is_shared(array) == shared, topic


def test_every_large_message_type_round_trips_exactly_through_shared_memory(context, spawn):
    received: list = []
    executor = _subscribe_all(context, received)
    publisher = spawn("shm_peer", "--role", "pub", "--count", "2", "--wait-subs", "1", "--linger", "5")
    _spin_until(executor, lambda: len(received) >= 2 * len(TOPICS))
    report = publisher.wait_event("published", timeout=30.0)
    assert sorted(t for t, _ in received) == sorted(TOPICS * 2)
    _check(received, shared=True)
    assert report["shared"] == {topic: 2 for topic in TOPICS}  # every one through a segment


def test_falls_back_to_zeromq_when_the_peers_are_on_tcp(context, spawn, monkeypatch):
    monkeypatch.setenv("DPTPU_TRANSPORT", "tcp")
    received: list = []
    executor = _subscribe_all(context, received)
    publisher = spawn("shm_peer", "--role", "pub", "--count", "1", "--wait-subs", "1", "--linger", "5",
                      env={"DPTPU_TRANSPORT": "tcp"})
    _spin_until(executor, lambda: len(received) >= len(TOPICS))
    report = publisher.wait_event("published", timeout=30.0)
    assert sorted(t for t, _ in received) == sorted(TOPICS)
    _check(received, shared=False)
    assert report["shared"] == {topic: 0 for topic in TOPICS}


def test_one_subscriber_that_cannot_map_gets_everything_through_zeromq(context, spawn):
    received: list = []
    executor = _subscribe_all(context, received)  # this process could map...
    other = spawn("shm_peer", "--role", "sub", "--linger", "20", env={"DPTPU_SHM": "off"})  # ...this one cannot
    other.wait_event("ready", timeout=20.0)
    publisher = spawn("shm_peer", "--role", "pub", "--count", "1", "--wait-subs", "2", "--linger", "5")
    _spin_until(executor, lambda: len(received) >= len(TOPICS))
    report = publisher.wait_event("published", timeout=30.0)
    _check(received, shared=False)
    assert report["shared"] == {topic: 0 for topic in TOPICS}
    for _ in TOPICS:
        event = other.wait_event("received", timeout=20.0)
        assert event["equal"] and not event["shared"]


def test_a_slow_subscriber_never_reads_a_segment_being_written_again(spawn):
    slow = spawn("shm_peer", "--role", "sub", "--delay", "0.05", "--linger", "30")
    slow.wait_event("ready", timeout=20.0)
    publisher = spawn("shm_peer", "--role", "pub", "--count", "8", "--period", "0.005", "--wait-subs", "1",
                      "--linger", "10")
    report = publisher.wait_event("published", timeout=30.0)
    assert report["shared"] == dict.fromkeys(TOPICS, 8)  # all through shared memory, far faster than it reads
    # it reads them one by one (queues of depth 10 hold all 8 of each topic) while the publisher has gone on
    events = [slow.wait_event("received", timeout=30.0) for _ in range(8 * len(TOPICS))]
    assert all(event["equal"] and event["shared"] for event in events)  # each one read after 50 ms, intact
    assert sorted(event["round"] for event in events) == sorted(list(range(8)) * len(TOPICS))


def _memfd_maps(pid: int) -> int:
    return sum("memfd:dptpu" in line for line in Path(f"/proc/{pid}/maps").read_text().splitlines())


def test_a_killed_publisher_leaves_no_segment(context, spawn):
    before = sorted(os.listdir("/dev/shm"))
    received: list = []
    executor = _subscribe_all(context, received)
    publisher = spawn("shm_peer", "--role", "pub", "--count", "1000", "--period", "0.02", "--wait-subs", "1",
                      "--linger", "30")
    _spin_until(executor, lambda: len(received) >= 3 * len(TOPICS))
    os.kill(publisher.proc.pid, signal.SIGKILL)
    publisher.proc.wait(timeout=10)
    held = received[:len(TOPICS)]
    _check(held, shared=True)  # what this subscriber holds stays intact after the publisher's death
    assert _memfd_maps(os.getpid()) > 0
    del held
    received.clear()
    gc.collect()
    deadline = time.monotonic() + 10.0
    while shared_memory.mapped_segment_count() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)  # messages still queued are taken (and dropped) meanwhile
        received.clear()
        gc.collect()
    assert shared_memory.mapped_segment_count() == 0  # the runtime's I/O thread unmapped them (once a second)
    assert _memfd_maps(os.getpid()) == 0  # unmapped: the kernel has freed the dead publisher's memory
    assert sorted(os.listdir("/dev/shm")) == before


def test_a_killed_subscriber_leaves_no_segment_and_the_publisher_goes_on(context, spawn):
    before = sorted(os.listdir("/dev/shm"))
    received: list = []
    executor = _subscribe_all(context, received)
    doomed = spawn("shm_peer", "--role", "sub", "--linger", "30")
    doomed.wait_event("ready", timeout=20.0)
    publisher = spawn("shm_peer", "--role", "pub", "--count", "12", "--period", "0.1", "--wait-subs", "2",
                      "--linger", "10")
    doomed.wait_event("received", timeout=30.0)
    os.kill(doomed.proc.pid, signal.SIGKILL)
    counts = dict.fromkeys(TOPICS, 0)
    shared = dict.fromkeys(TOPICS, 0)

    def take_all():  # keep none of the messages (a subscriber that holds them all fills the pool)
        for topic, msg in received:
            counts[topic] += 1
            shared[topic] += is_shared(first_array(msg))
            if round_of(msg) == 11:
                _check([(topic, msg)], shared=True)
        received.clear()
        return sum(counts.values()) >= 12 * len(TOPICS)

    _spin_until(executor, take_all, timeout=60.0)
    report = publisher.wait_event("published", timeout=30.0)
    assert counts == dict.fromkeys(TOPICS, 12)  # the survivor got every message
    assert all(count >= 8 for count in shared.values()), shared  # through shared memory once the dead one left
    assert report["published"] == dict.fromkeys(TOPICS, 12) and report["shared"] == shared
    gc.collect()
    assert sorted(os.listdir("/dev/shm")) == before


@pytest.mark.parametrize("subscriber_shm", ["auto", "off"])
def test_loaned_arrays_are_published_without_a_copy_or_copied_out_for_a_subscriber_that_cannot_map(
        context, spawn, subscriber_shm):
    subscriber = spawn("shm_peer", "--role", "sub", "--linger", "20", env={"DPTPU_SHM": subscriber_shm})
    subscriber.wait_event("ready", timeout=20.0)
    node = Node("loaner", context=context)
    publisher = node.create_publisher(Image, "/shm/mono16", 10)
    assert publisher.wait_for_subscriptions(1, timeout_sec=20.0)

    def no_copy(*args, **kwargs):
        raise AssertionError("a loaned message was copied into a segment")

    publisher._pool.write = no_copy
    # a loan is worth it only when every subscriber can map (else it is copied out at publish)
    assert publisher.can_loan_messages(480 * 640 * 2) == (subscriber_shm == "auto")
    assert not publisher.can_loan_messages(1000)  # below DPTPU_SHM_MIN_BYTES: through ZeroMQ
    for index in range(3):
        expected = large_messages(index)["/shm/mono16"]
        (pixels,) = publisher.borrow_loaned_arrays([((480, 640), np.uint16)])
        np.copyto(pixels, expected.to_array())  # the writer fills the loaned array in place
        publisher.publish(Image.from_array(pixels, "mono16", header=expected.header))
        assert not pixels.flags.writeable  # the subscribers' now
        event = subscriber.wait_event("received", timeout=20.0)
        assert (event["topic"], event["round"], event["equal"]) == ("/shm/mono16", index, True)
        assert event["shared"] == (subscriber_shm == "auto")
    assert publisher.shared_count == (3 if subscriber_shm == "auto" else 0)
    assert publisher._pool.segment_count <= 2  # a segment copied out (or let go by the reader) serves again
    (unused,) = publisher.borrow_loaned_arrays([((480, 640), np.uint16)])
    publisher.return_loaned_arrays([unused])
    assert not publisher._loans


def test_a_loan_let_go_unpublished_goes_back_to_the_pool(context):
    node = Node("loan_dropper", context=context)
    publisher = node.create_publisher(Image, "/shm/dropped", 10)
    (pixels,) = publisher.borrow_loaned_arrays([((480, 640), np.uint16)])
    first = pixels.ctypes.data
    del pixels  # a frame the writer dropped (e.g. one no Trigger claimed): garbage, never published
    gc.collect()
    for _ in range(3):  # each borrow takes the let-go segment back first: the pool never grows
        (pixels,) = publisher.borrow_loaned_arrays([((480, 640), np.uint16)])
        assert pixels.ctypes.data == first and publisher._pool.segment_count == 1
        del pixels
    publisher.publish(Image())  # no arrays: through ZeroMQ, and the last let-go loan is taken back too
    assert not publisher._loans and publisher._pool.segment_count == 1
    (kept,) = publisher.borrow_loaned_arrays([((480, 640), np.uint16)])  # a loan still held is not taken back
    (other,) = publisher.borrow_loaned_arrays([((480, 640), np.uint16)])
    assert kept.ctypes.data != other.ctypes.data and publisher._pool.segment_count == 2
    # a loan that was returned (or published) is done with: its arrays' end queues nothing to take back
    publisher.return_loaned_arrays([kept])
    del kept
    gc.collect()
    assert not publisher._abandoned and len(publisher._loans) == 1
    del other  # the one still lent: queued, and taken back at the next borrow
    gc.collect()
    assert len(publisher._abandoned) == 1
    (again,) = publisher.borrow_loaned_arrays([((480, 640), np.uint16)])
    assert not publisher._abandoned and len(publisher._loans) == 1 and publisher._pool.segment_count == 2


def test_a_subscriber_that_cannot_open_segments_unsubscribes_and_gets_zeromq(spawn, domain_dir):
    listener = spawn("listener", "--count", "1", "--timeout", "30")
    listener.wait_event("ready")
    context = zmq.Context()
    sock = context.socket(zmq.XPUB)
    sock.setsockopt(zmq.XPUB_VERBOSER, 1)
    endpoint = f"ipc://{domain_dir}/ep/shmforger"
    topic = shm_topic(b"/chatter", host_key())  # the listener's host key: the same user on the same kernel
    try:
        sock.bind(endpoint)
        _announce_raw_publisher(domain_dir, endpoint, "/chatter")
        events: list[bytes] = []
        deadline = time.monotonic() + 15.0
        while b"\x01" + topic not in events and time.monotonic() < deadline:
            if sock.poll(500):
                events.append(sock.recv())
        assert b"\x01" + topic in events, events  # it asked for descriptors
        gid = uuid.uuid4().bytes
        header = encode("/chatter", String(data="never"))[1]
        for seq in range(1, SHM_GIVE_UP + 1):  # descriptors of a process that does not exist
            sock.send_multipart([topic, header, pack_descriptor(2**22 + 4321, 5, 1, bytes(16), seq, 4096, [(64, 8)]),
                                 pack_envelope(0, seq, 0, gid)])
        deadline = time.monotonic() + 15.0
        while b"\x00" + topic not in events and time.monotonic() < deadline:
            if sock.poll(500):
                events.append(sock.recv())
        assert b"\x00" + topic in events  # it gave up shared memory
        sock.send_multipart(encode("/chatter", String(data="good")) + [pack_envelope(0, SHM_GIVE_UP + 1, 0, gid)])
        done = listener.wait_event("done", timeout=20.0)
        assert done["received"] == ["good"] and done["lost_count"] == SHM_GIVE_UP
        assert listener.wait_for_stderr("taking every message through ZeroMQ from now on"), listener.stderr
    finally:
        sock.close(linger=0)
        context.term()
