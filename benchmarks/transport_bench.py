"""Speed of the node graph runtime's transport against raw pyzmq, side by side in one run (not a test).

Run it as ``dptpu bench transport [--json] [--size full|small]`` or ``python benchmarks/transport_bench.py``.
Every measurement uses two OS processes on this machine, talking over ipc (Unix sockets), and each
pair is run twice, once through ``dptpu.graph`` ("ours") and once with bare pyzmq sockets ("raw"):

(a) Throughput of a 24x480x640 uint8 message (7,372,800 bytes; ``--size small``: 2x48x64).

    - ours: a node publishes a ``FrameStack`` message (this file's own type: ``seq``, ``phase``,
      ``pool_index`` scalars and the ``(F, H, W)`` uint8 array as one raw frame) with
      ``Publisher.publish``; a node in the other process receives it through
      ``create_subscription`` and the executor's callback (decoded: a read-only numpy view).
    - raw: a pyzmq PUB socket sends ``[topic, 10-byte header, array]`` with ``copy=False`` to a SUB
      socket, which receives with ``copy=False``.

    Both sides are flow-controlled the same way, so neither measures dropped messages: the receiver
    acknowledges every message on a separate raw PUSH/PULL socket pair (8 bytes), and the sender keeps
    at most ``--window`` (default 4) messages in flight. Throughput = messages x bytes / (time from the
    first send to the last acknowledgement), in MB/s (10**6 bytes). The CPU time of the whole sender
    process (every thread) during the timed rounds is reported per message. The messages cycle through a pool of
    4 different random arrays; the receiver checks every warm-up message bit for bit and every timed
    message on a fixed sample of ~1800 bytes, plus the sequence (no gap, no repeat).

(b) Round-trip latency of a 64-byte payload.

    - ours: a ping node publishes a ``Ping`` message (``seq``, ``phase`` and a 64-byte uint8 array);
      a pong node's subscription callback publishes it back on another topic; the ping node's main
      thread spins its executor until the pong's callback has run.
    - raw: two sockets per process, PUB -> SUB one way and PUB -> SUB back; the ping process sends
      ``[topic, header, 64 bytes]`` and blocks in ``recv``.

    Each round trip is timed with ``time.perf_counter`` in the ping process; p50 and p99 over all
    timed round trips (after a warm-up).

By default each sender process runs on the first half of the CPUs this process may use and each
receiver on the second half (``os.sched_setaffinity``, inherited by every thread), so the scheduler
cannot move threads between the two sides; ``--no-pin`` lets the OS place threads freely (on a 2-CPU
machine that makes the throughput figures swing by +-50 % from run to run; see docs/benchmarks.md).

Reported ratios: ``throughput_ratio = ours / raw`` (goal >= 0.9) and ``latency_p50_ratio``,
``latency_p99_ratio = ours / raw`` (goal <= 2). Both variants run in the same invocation, one after
the other, on the same machine; compare ratios within one run only.

(c) Shared memory (``shared_memory`` in the report). "Ours" is the runtime as it is configured by default: on
    one host, over ipc, a message whose arrays hold at least ``DPTPU_SHM_MIN_BYTES`` (64 KiB) travels through
    shared memory (``dptpu.graph.shared_memory``: one copy into the publisher's segment, the subscriber's arrays
    are views of it). Beside it, in the same run: ours with ``DPTPU_SHM=off`` (the ZeroMQ path, as before
    shared memory) and a ``memcpy`` of the same bytes in one process (``np.copyto`` between two preallocated
    arrays, the sender's CPUs, the same pool of 4 arrays: what moving the bytes once costs). Ratios:
    ``throughput_ratio`` (ours / raw pyzmq, goal >= 3 for a 7.4 MB message), ``zeromq_throughput_ratio`` (ours
    over ZeroMQ / raw) and ``memcpy_ratio`` (ours / memcpy, goal >= 0.5: within 2x of a memcpy);
    ``shared_count``: the messages ours sent through shared memory (0 below the threshold, e.g. ``--size small``).

(d) Writers that fill in place (``shared_memory.loaned``). "Ours, loaned": the sender borrows the message's array
    in a segment (``Publisher.borrow_loaned_arrays``), fills it with the message's bytes (``np.copyto`` of the
    pool's array: the work of making the message, which the raw sender does not do at all, its arrays being made
    before the timed rounds) and publishes it (no copy). Its figures leave the fill out: each round's time and the
    sender's CPU less the fills' own wall and thread CPU time (measured around each ``np.copyto``); so every
    variant times the same thing, moving a message that exists from one process to the other. The figures with
    the fills (``gross``) and the fill alone (``fill_us_per_message``) are reported beside them. Ratios for each
    writer (``writers``): ``publish`` (a ready-made array, one copy into the segment) and ``loaned``, each against
    raw pyzmq and the memcpy, by wall time and per CPU second, and ``loaned_with_fills`` (the fills timed too).
    The per-CPU-second ratios are exact for the loaned writer (CPU times add up); its wall figures bracket the
    truth: with the fills taken off they are an upper bound (the receiver works on earlier messages while the
    sender fills the next one, so not all of a fill's time is on the critical path), with them a lower bound (they
    time making the message, which the raw variant does not).

The processes join a private graph (a fresh ``DPTPU_DISCOVERY_DIR`` under /tmp, domain 0), so the
benchmark never sees or disturbs another graph.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

FULL_SHAPE = (24, 480, 640)
SMALL_SHAPE = (2, 48, 64)
PAYLOAD_BYTES = 64
POOL_SIZE = 4
SAMPLE_STRIDE = 4093  # bytes between two sampled bytes of a timed message (prime: no alignment with rows)
FRAMES_TOPIC = "/bench/frames"
PING_TOPIC = "/bench/ping"
PONG_TOPIC = "/bench/pong"
WARMUP, TIMED, STOP = 0, 1, 2  # message phases
PIPE_HWM = 100  # raw sockets get the same high-water mark as a RELIABLE subscription of the runtime
THROUGHPUT_GOAL = 0.9
LATENCY_GOAL = 2.0
#: Issue 20's goals for a large message through shared memory: ours / raw pyzmq, and ours / a memcpy.
SHARED_THROUGHPUT_GOAL = 3.0
MEMCPY_GOAL = 0.5
#: Defaults per --size: timed messages per round, rounds, timed round trips per round, warm-ups.
SIZES = {
    "full": {"shape": FULL_SHAPE, "messages": 100, "rounds": 3, "round_trips": 2000, "warmup_messages": 4,
             "warmup_round_trips": 200},
    "small": {"shape": SMALL_SHAPE, "messages": 20, "rounds": 1, "round_trips": 50, "warmup_messages": 4,
              "warmup_round_trips": 20},
}
DEFAULT_WINDOW = 4
CHILD_TIMEOUT_S = 300.0
_HEADER = struct.Struct("<QBB")  # raw header: seq, phase, pool index
_ACK = struct.Struct("<Q")
_STARTED = time.monotonic()


# --------------------------------------------------------------------------------------------------
# Message types (registered once per process) and payloads
# --------------------------------------------------------------------------------------------------

def bench_types():
    """``(FrameStack, Ping)``: this benchmark's message types, registered in this process on first use."""
    from dptpu.messages.registry import is_registered, lookup
    from dptpu.messages.schema import Message, array, message, scalar

    if is_registered("dptpu_bench/msg/FrameStack"):
        return lookup("dptpu_bench/msg/FrameStack"), lookup("dptpu_bench/msg/Ping")

    @message("dptpu_bench/msg/FrameStack", version=1)
    class FrameStack(Message):
        seq: int = scalar("uint64")
        phase: int = scalar("uint8")
        pool_index: int = scalar("uint8")
        frames: np.ndarray = array("uint8", ("F", "H", "W"))

    @message("dptpu_bench/msg/Ping", version=1)
    class Ping(Message):
        seq: int = scalar("uint64")
        phase: int = scalar("uint8")
        data: np.ndarray = array("uint8", ("N",))

    return FrameStack, Ping


def make_pool(shape) -> list[np.ndarray]:
    """``POOL_SIZE`` different seeded random uint8 arrays of ``shape`` (the same in every process)."""
    return [np.random.default_rng(index).integers(0, 256, size=shape, dtype=np.uint8) for index in range(POOL_SIZE)]


def _samples(pool) -> list[np.ndarray]:
    return [array.reshape(-1)[::SAMPLE_STRIDE].copy() for array in pool]


class IntegrityCheck:
    """What a receiver verifies: warm-up messages bit for bit, timed ones on a sample, sequence order."""

    def __init__(self, shape):
        self.pool = make_pool(shape)
        self.samples = _samples(self.pool)
        self.shape = tuple(shape)
        self.received = self.timed = self.full_checks = self.failures = self.gaps = 0
        self.last_seq = None
        # CPU time over the timed messages: this (main) thread's, and the whole process's (with libzmq's I/O thread)
        self.timed_cpu_start = self.timed_cpu_end = self.timed_process_cpu_start = self.timed_process_cpu_end = None

    def check(self, seq: int, phase: int, pool_index: int, frames: np.ndarray) -> None:
        self.received += 1
        if self.last_seq is not None and seq != self.last_seq + 1:
            self.gaps += 1
        self.last_seq = seq
        if phase == STOP:
            self.timed_cpu_end, self.timed_process_cpu_end = time.thread_time(), time.process_time()
            return
        if phase == TIMED and self.timed_cpu_start is None:
            self.timed_cpu_start, self.timed_process_cpu_start = time.thread_time(), time.process_time()
        ok = frames.shape == self.shape and frames.dtype == np.uint8 and 0 <= pool_index < POOL_SIZE
        if ok and phase == WARMUP:
            self.full_checks += 1
            ok = bool(np.array_equal(frames, self.pool[pool_index]))
        elif ok:
            self.timed += 1
            ok = bool(np.array_equal(frames.reshape(-1)[::SAMPLE_STRIDE], self.samples[pool_index]))
        self.failures += not ok

    def report(self) -> dict:
        report = {"received": self.received, "timed": self.timed, "full_checks": self.full_checks,
                  "failures": self.failures, "sequence_gaps": self.gaps}
        if self.timed_cpu_start is not None and self.timed_cpu_end is not None and self.timed > 1:
            # the receiving thread's own CPU a message (decode, executor, callback), without libzmq's I/O thread
            report["main_thread_cpu_us_per_message"] = (self.timed_cpu_end - self.timed_cpu_start) / self.timed * 1e6
            cpu_s = self.timed_process_cpu_end - self.timed_process_cpu_start
            report["cpu_us_per_message"] = cpu_s / self.timed * 1e6
        return report


def _emit(**fields) -> None:
    print(json.dumps(fields), flush=True)


# --------------------------------------------------------------------------------------------------
# Throughput: senders and receivers
# --------------------------------------------------------------------------------------------------

def _run_sender(send, receive_ack, options, untimed=None) -> dict:
    """Warm up until the link carries messages, then run the timed rounds; returns the sender's figures.

    ``send(seq, phase, pool_index)`` sends one message; ``receive_ack(timeout_ms)`` returns an acked
    sequence number or None. ``untimed()``, when given, returns the ``(wall s, CPU s)`` the sender has spent so far
    on work that is not transport (a loaned writer's fill): taken off each round's time and off the CPU, and
    reported as ``rounds_gross_s``, ``gross_cpu_s_per_message`` and ``fill_*``.
    """
    seq = 0
    while True:  # a subscriber joins late: send single warm-up messages until one is acknowledged
        send(seq, WARMUP, seq % POOL_SIZE)
        seq += 1
        if receive_ack(200) is not None:
            break
    while receive_ack(50) is not None:  # late acks of the probes
        pass
    for _ in range(options.warmup_messages):
        send(seq, WARMUP, seq % POOL_SIZE)
        seq += 1
        if receive_ack(10_000) is None:
            raise RuntimeError("a warm-up message was not acknowledged within 10 s")
    rounds_s, rounds_gross_s = [], []
    cpu_start = time.process_time()
    untimed_start = untimed() if untimed is not None else (0.0, 0.0)
    for _ in range(options.rounds):
        sent = acked = 0
        round_untimed = untimed()[0] if untimed is not None else 0.0
        start = time.perf_counter()
        while acked < options.messages:
            while sent < options.messages and sent - acked < options.window:
                send(seq, TIMED, seq % POOL_SIZE)
                seq += 1
                sent += 1
            if receive_ack(10_000) is None:
                raise RuntimeError(f"no acknowledgement within 10 s ({acked} of {options.messages} acked)")
            acked += 1
        gross_s = time.perf_counter() - start
        rounds_gross_s.append(gross_s)
        rounds_s.append(gross_s - ((untimed()[0] if untimed is not None else 0.0) - round_untimed))
    cpu_s = time.process_time() - cpu_start  # every thread of the sender process, timed rounds only
    untimed_wall_s, untimed_cpu_s = (np.subtract(untimed(), untimed_start) if untimed is not None else (0.0, 0.0))
    send(seq, STOP, 0)
    receive_ack(5_000)
    timed = options.rounds * options.messages
    result = {"rounds_s": rounds_s, "cpu_s_per_message": (cpu_s - untimed_cpu_s) / timed}
    if untimed is not None:
        result.update(rounds_gross_s=rounds_gross_s, gross_cpu_s_per_message=cpu_s / timed,
                      fill_wall_s_per_message=float(untimed_wall_s) / timed,
                      fill_cpu_s_per_message=float(untimed_cpu_s) / timed)
    return result


def _data_context():
    """The raw measured sockets' own ZeroMQ context (one I/O thread), apart from the acknowledgement
    channel's ``zmq.Context.instance()``, as the runtime's sockets are in ``dptpu.graph``."""
    import zmq

    return zmq.Context(io_threads=1)


def _ack_pull(endpoint: str):
    import zmq

    context = zmq.Context.instance()
    pull = context.socket(zmq.PULL)
    pull.setsockopt(zmq.LINGER, 0)
    pull.bind(endpoint)

    def receive_ack(timeout_ms: int):
        if pull.poll(timeout_ms):
            return _ACK.unpack(pull.recv())[0]
        return None

    return pull, receive_ack


def _ack_push(endpoint: str):
    import zmq

    push = zmq.Context.instance().socket(zmq.PUSH)
    push.setsockopt(zmq.LINGER, 1000)
    push.connect(endpoint)
    return push


def role_ours_source(options) -> dict:
    import dptpu.graph as rclpy
    from dptpu.graph import QoSProfile

    frame_stack, _ = bench_types()
    pool = make_pool(options.shape)
    _pull, receive_ack = _ack_pull(options.ack)
    rclpy.init(args=[])
    try:
        node = rclpy.create_node("bench_source")
        publisher = node.create_publisher(frame_stack, FRAMES_TOPIC, QoSProfile(depth=2 * options.window))

        def send(seq, phase, pool_index):
            publisher.publish(frame_stack(seq=seq, phase=phase, pool_index=pool_index, frames=pool[pool_index]))

        return {**_run_sender(send, receive_ack, options), "shared_count": publisher.shared_count}
    finally:
        rclpy.try_shutdown()


def role_ours_loan_source(options) -> dict:
    """Ours with a writer that fills its message in a loaned segment (issue 20): the fills are not timed."""
    import dptpu.graph as rclpy
    from dptpu.graph import QoSProfile

    frame_stack, _ = bench_types()
    pool = make_pool(options.shape)
    _pull, receive_ack = _ack_pull(options.ack)
    fills = [0.0, 0.0]  # wall s, CPU s of the sender's fills so far
    rclpy.init(args=[])
    try:
        node = rclpy.create_node("bench_loan_source")
        publisher = node.create_publisher(frame_stack, FRAMES_TOPIC, QoSProfile(depth=2 * options.window))

        def send(seq, phase, pool_index):
            (frames,) = publisher.borrow_loaned_arrays([(options.shape, np.uint8)])
            wall_s, cpu_s = time.perf_counter(), time.thread_time()
            np.copyto(frames, pool[pool_index])  # the writer makes its message where it will be read
            fills[0] += time.perf_counter() - wall_s
            fills[1] += time.thread_time() - cpu_s
            publisher.publish(frame_stack(seq=seq, phase=phase, pool_index=pool_index, frames=frames))

        figures = _run_sender(send, receive_ack, options, untimed=lambda: (fills[0], fills[1]))
        return {**figures, "shared_count": publisher.shared_count}
    finally:
        rclpy.try_shutdown()


def role_ours_sink(options) -> dict:
    import dptpu.graph as rclpy
    from dptpu.graph import QoSProfile, SingleThreadedExecutor

    frame_stack, _ = bench_types()
    check = IntegrityCheck(options.shape)
    push = _ack_push(options.ack)
    stopped = []
    rclpy.init(args=[])
    try:
        node = rclpy.create_node("bench_sink")

        def on_message(msg):
            check.check(msg.seq, msg.phase, msg.pool_index, msg.frames)
            push.send(_ACK.pack(msg.seq))
            if msg.phase == STOP:
                stopped.append(True)

        subscription = node.create_subscription(frame_stack, FRAMES_TOPIC, on_message,
                                                QoSProfile(depth=2 * options.window))
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        deadline = time.monotonic() + CHILD_TIMEOUT_S
        while not stopped and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.5)
        return {**check.report(), "dropped_count": subscription.dropped_count}
    finally:
        rclpy.try_shutdown()


def role_memcpy(options) -> dict:
    """Copy the pool's arrays into a preallocated array, as many times and rounds as the senders send."""
    pool = make_pool(options.shape)
    target = np.empty_like(pool[0])
    for index in range(options.warmup_messages):
        np.copyto(target, pool[index % POOL_SIZE])
    rounds_s = []
    cpu_start = time.process_time()
    for _ in range(options.rounds):
        start = time.perf_counter()
        for index in range(options.messages):
            np.copyto(target, pool[index % POOL_SIZE])
        rounds_s.append(time.perf_counter() - start)
    cpu_s = time.process_time() - cpu_start
    same = bool(np.array_equal(target, pool[(options.messages - 1) % POOL_SIZE]))
    return {"rounds_s": rounds_s, "cpu_s_per_message": cpu_s / (options.rounds * options.messages), "intact": same}


def role_raw_source(options) -> dict:
    import zmq

    pool = make_pool(options.shape)
    _pull, receive_ack = _ack_pull(options.ack)
    pub = _data_context().socket(zmq.PUB)
    pub.setsockopt(zmq.SNDHWM, PIPE_HWM)
    pub.setsockopt(zmq.LINGER, 1000)
    pub.bind(options.data)
    topic = FRAMES_TOPIC.encode()

    def send(seq, phase, pool_index):
        pub.send_multipart([topic, _HEADER.pack(seq, phase, pool_index), pool[pool_index]], copy=False)

    return _run_sender(send, receive_ack, options)


def role_raw_sink(options) -> dict:
    import zmq

    check = IntegrityCheck(options.shape)
    push = _ack_push(options.ack)
    sub = _data_context().socket(zmq.SUB)
    sub.setsockopt(zmq.RCVHWM, PIPE_HWM)
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.SUBSCRIBE, FRAMES_TOPIC.encode())
    sub.connect(options.data)
    deadline = time.monotonic() + CHILD_TIMEOUT_S
    while time.monotonic() < deadline:
        if not sub.poll(500):
            continue
        _topic, header, data = sub.recv_multipart(copy=False)
        seq, phase, pool_index = _HEADER.unpack(header.bytes)
        frames = np.frombuffer(data.buffer, dtype=np.uint8)
        check.check(seq, phase, pool_index, frames.reshape(options.shape) if frames.size == np.prod(options.shape)
                    else frames)
        push.send(_ACK.pack(seq))
        if phase == STOP:
            break
    return check.report()


# --------------------------------------------------------------------------------------------------
# Latency: ping and pong
# --------------------------------------------------------------------------------------------------

def _run_ping(round_trip, options) -> dict:
    """``round_trip(seq, phase, timeout_s)`` -> True when the pong came back; returns the timings."""
    seq = 0
    while not round_trip(seq, WARMUP, 0.2):  # until both directions are connected
        seq += 1
    seq += 1
    for _ in range(options.warmup_round_trips):
        if not round_trip(seq, WARMUP, 10.0):
            raise RuntimeError("a warm-up round trip got no answer within 10 s")
        seq += 1
    rounds_us = []
    for _ in range(options.rounds):
        times_us = []
        for _ in range(options.round_trips):
            start = time.perf_counter()
            if not round_trip(seq, TIMED, 10.0):
                raise RuntimeError(f"round trip {seq} got no answer within 10 s")
            times_us.append((time.perf_counter() - start) * 1e6)
            seq += 1
        rounds_us.append(times_us)
    round_trip(seq, STOP, 2.0)
    return {"rounds_us": rounds_us}


def role_ours_ping(options) -> dict:
    import dptpu.graph as rclpy
    from dptpu.graph import QoSProfile, SingleThreadedExecutor

    _, ping_type = bench_types()
    payload = np.arange(PAYLOAD_BYTES, dtype=np.uint8)
    rclpy.init(args=[])
    try:
        node = rclpy.create_node("bench_ping")
        publisher = node.create_publisher(ping_type, PING_TOPIC, QoSProfile(depth=10))
        answered = {"seq": -1, "bad": 0}

        def on_pong(msg):
            answered["seq"] = msg.seq
            answered["bad"] += not np.array_equal(msg.data, payload)

        node.create_subscription(ping_type, PONG_TOPIC, on_pong, QoSProfile(depth=10))
        executor = SingleThreadedExecutor()
        executor.add_node(node)

        def round_trip(seq, phase, timeout_s):
            publisher.publish(ping_type(seq=seq, phase=phase, data=payload))
            deadline = time.perf_counter() + timeout_s
            while answered["seq"] != seq:
                remaining = deadline - time.perf_counter()
                if remaining <= 0:
                    return False
                executor.spin_once(timeout_sec=remaining)
            return True

        result = _run_ping(round_trip, options)
        return {**result, "payload_mismatches": answered["bad"]}
    finally:
        rclpy.try_shutdown()


def role_ours_pong(options) -> dict:
    import dptpu.graph as rclpy
    from dptpu.graph import QoSProfile, SingleThreadedExecutor

    _, ping_type = bench_types()
    rclpy.init(args=[])
    try:
        node = rclpy.create_node("bench_pong")
        publisher = node.create_publisher(ping_type, PONG_TOPIC, QoSProfile(depth=10))
        state = {"count": 0, "stop": False}

        def on_ping(msg):
            publisher.publish(ping_type(seq=msg.seq, phase=msg.phase, data=msg.data))
            state["count"] += 1
            state["stop"] = msg.phase == STOP

        node.create_subscription(ping_type, PING_TOPIC, on_ping, QoSProfile(depth=10))
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        deadline = time.monotonic() + CHILD_TIMEOUT_S
        while not state["stop"] and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.5)
        time.sleep(0.2)  # let the last pong leave before the sockets close
        return {"answered": state["count"]}
    finally:
        rclpy.try_shutdown()


def _raw_pair(bind_endpoint: str, connect_endpoint: str):
    import zmq

    context = zmq.Context.instance()
    pub = context.socket(zmq.PUB)
    pub.setsockopt(zmq.SNDHWM, PIPE_HWM)
    pub.setsockopt(zmq.LINGER, 1000)
    pub.bind(bind_endpoint)
    sub = context.socket(zmq.SUB)
    sub.setsockopt(zmq.RCVHWM, PIPE_HWM)
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(connect_endpoint)
    return pub, sub


def role_raw_ping(options) -> dict:
    pub, sub = _raw_pair(options.data, options.ack)
    payload = np.arange(PAYLOAD_BYTES, dtype=np.uint8).tobytes()
    topic = PING_TOPIC.encode()
    bad = [0]

    def round_trip(seq, phase, timeout_s):
        pub.send_multipart([topic, _HEADER.pack(seq, phase, 0), payload])
        deadline = time.perf_counter() + timeout_s
        while True:
            remaining_ms = (deadline - time.perf_counter()) * 1000.0
            if remaining_ms <= 0 or not sub.poll(remaining_ms):
                return False
            _topic, header, data = sub.recv_multipart()
            bad[0] += data != payload
            if _HEADER.unpack(header)[0] == seq:
                return True

    result = _run_ping(round_trip, options)
    return {**result, "payload_mismatches": bad[0]}


def role_raw_pong(options) -> dict:
    pub, sub = _raw_pair(options.ack, options.data)
    topic = PONG_TOPIC.encode()
    count = 0
    deadline = time.monotonic() + CHILD_TIMEOUT_S
    while time.monotonic() < deadline:
        if not sub.poll(500):
            continue
        _topic, header, data = sub.recv_multipart()
        pub.send_multipart([topic, header, data])
        count += 1
        if _HEADER.unpack(header)[1] == STOP:
            break
    time.sleep(0.2)
    return {"answered": count}


ROLES = {"ours-source": role_ours_source, "ours-loan-source": role_ours_loan_source, "ours-sink": role_ours_sink,
         "raw-source": role_raw_source,
         "raw-sink": role_raw_sink, "ours-ping": role_ours_ping, "ours-pong": role_ours_pong,
         "raw-ping": role_raw_ping, "raw-pong": role_raw_pong, "memcpy": role_memcpy}


# --------------------------------------------------------------------------------------------------
# Coordinator
# --------------------------------------------------------------------------------------------------

def _resolve(args) -> argparse.Namespace:
    size = getattr(args, "size", None) or "full"
    if size not in SIZES:
        raise ValueError(f"--size must be 'full' or 'small'; got {size!r}")
    options = dict(SIZES[size])
    for key in ("messages", "rounds", "round_trips", "window", "repeat"):
        value = getattr(args, key, None)
        if value is not None:
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"--{key.replace('_', '-')} must be an integer >= 1; got {value!r}")
            options[key] = value
    options.setdefault("window", DEFAULT_WINDOW)
    options.setdefault("repeat", 1)
    return argparse.Namespace(size=size, json=bool(getattr(args, "json", False)),
                              pin=not bool(getattr(args, "no_pin", False)), **options)


RECEIVER_ROLES = ("ours-sink", "raw-sink", "ours-pong", "raw-pong")


def pinned_cpus(role: str) -> list[int] | None:
    """The CPUs a ``--pin`` child runs on: senders the first half of the usable ones, receivers the rest."""
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        return None
    half = len(cpus) // 2
    return cpus[half:] if role in RECEIVER_ROLES else cpus[:half]


def _child_command(role: str, options, ack: str, data: str) -> list[str]:
    return [sys.executable, str(Path(__file__).resolve()), "--role", role, "--shape",
            ",".join(str(n) for n in options.shape), "--messages", str(options.messages), "--rounds",
            str(options.rounds), "--round-trips", str(options.round_trips), "--window", str(options.window),
            "--warmup-messages", str(options.warmup_messages), "--warmup-round-trips",
            str(options.warmup_round_trips), "--ack", ack, "--data", data, *(["--pin"] if options.pin else [])]


def _run_pair(receiver: str, sender: str, options, env: dict, folder: Path, tag: str) -> tuple[dict, dict]:
    """Start the receiver and the sender; return their JSON results (RuntimeError with stderr on failure)."""
    ack, data = f"ipc://{folder}/{tag}-a", f"ipc://{folder}/{tag}-d"
    processes = []
    try:
        for role in (receiver, sender):
            processes.append(subprocess.Popen(_child_command(role, options, ack, data), stdout=subprocess.PIPE,
                                              stderr=subprocess.PIPE, text=True, env=env))
        results = {}
        # The sender first: it fails within seconds when the receiver is missing, while a receiver
        # waits for a sender that died until CHILD_TIMEOUT_S.
        for role, process in ((sender, processes[1]), (receiver, processes[0])):
            try:
                out, err = process.communicate(timeout=CHILD_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                raise RuntimeError(f"benchmark process {role} did not finish within {CHILD_TIMEOUT_S:g} s") from None
            lines = [line for line in out.splitlines() if line.startswith("{")]
            if process.returncode != 0 or not lines:
                raise RuntimeError(f"benchmark process {role} failed (exit code {process.returncode}):\n{err[-3000:]}")
            results[role] = json.loads(lines[-1])
        return results[receiver], results[sender]
    finally:
        for process in processes:
            if process.poll() is None:
                process.kill()
                process.wait()


def _run_single(role: str, options, env: dict) -> dict:
    """Run one child (the memcpy) and return its JSON result."""
    process = subprocess.run(_child_command(role, options, "", ""), capture_output=True, text=True, env=env,
                             timeout=CHILD_TIMEOUT_S)
    lines = [line for line in process.stdout.splitlines() if line.startswith("{")]
    if process.returncode != 0 or not lines:
        raise RuntimeError(f"benchmark process {role} failed (exit code {process.returncode}):\n"
                           f"{process.stderr[-3000:]}")
    return json.loads(lines[-1])


def _pooled(results: list[dict]) -> dict:
    """One result dict from the same role's results of several repeats: lists joined, counts added."""
    if len(results) == 1:
        return results[0]
    pooled = {}
    for key, value in results[0].items():
        values = [result[key] for result in results]
        if isinstance(value, list):
            pooled[key] = [item for item in values for item in item]
        elif isinstance(value, bool) or not isinstance(value, (int, float)):
            pooled[key] = value
        elif key.endswith("_per_message"):
            pooled[key] = float(np.mean(values))
        else:
            pooled[key] = sum(values)
    return pooled


def _throughput_figures(sender: dict, receiver: dict, options) -> dict:
    nbytes = int(np.prod(options.shape))
    rates = [options.messages * nbytes / seconds / 1e6 for seconds in sender["rounds_s"]]
    expected = options.repeat * options.rounds * options.messages
    intact = (receiver["failures"] == 0 and receiver["sequence_gaps"] == 0 and receiver["timed"] == expected
              and receiver["full_checks"] >= options.repeat * options.warmup_messages)
    cpu_us = sender["cpu_s_per_message"] * 1e6 + receiver.get("cpu_us_per_message", float("nan"))
    return {"mb_per_s": float(np.median(rates)), "rounds_mb_per_s": rates,
            "messages_per_s": float(np.median(rates)) * 1e6 / nbytes,
            "sender_cpu_us_per_message": sender["cpu_s_per_message"] * 1e6, "receiver": receiver,
            "cpu_us_per_message": cpu_us, "cpu_mb_per_s": nbytes / cpu_us, "intact": bool(intact)}


def _latency_figures(ping: dict, pong: dict, options) -> dict:
    times_us = np.concatenate([np.asarray(r, dtype=np.float64) for r in ping["rounds_us"]])
    return {"p50_us": float(np.percentile(times_us, 50)), "p99_us": float(np.percentile(times_us, 99)),
            "mean_us": float(times_us.mean()), "min_us": float(times_us.min()), "round_trips": int(times_us.size),
            "answered": pong["answered"], "intact": ping["payload_mismatches"] == 0}


def machine() -> dict:
    import zmq

    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cores": os.cpu_count(), "cpu": cpu, "python": platform.python_version(), "pyzmq": zmq.__version__,
            "libzmq": zmq.zmq_version(), "platform": platform.platform()}


def measure(args) -> dict:
    """Run both measurements, ours and raw side by side; return the report (see the module docstring)."""
    options = _resolve(args)
    folder = Path(tempfile.mkdtemp(prefix="dtb", dir="/tmp"))
    env = {key: value for key, value in os.environ.items()
           if key not in ("DPTPU_TRANSPORT", "DPTPU_TCP_INTERFACE", "DPTPU_CURVE_SECRET_KEY",
                          "DPTPU_CURVE_AUTHORIZED_KEYS", "DPTPU_PEERS", "ROS_DOMAIN_ID")}
    repo_root = str(Path(__file__).resolve().parents[1])
    env.update({"DPTPU_DISCOVERY_DIR": str(folder / "graph"), "DPTPU_DOMAIN_ID": "0",
                "PYTHONPATH": repo_root + os.pathsep + env.get("PYTHONPATH", "")})
    zeromq_env = dict(env, DPTPU_SHM="off")  # ours as before shared memory: every byte through ZeroMQ
    # (receiver, sender, tag, environment): raw and ours alternate, so a load that drifts hits both alike
    pairs = (("raw-sink", "raw-source", "rt", env), ("ours-sink", "ours-source", "ot", env),
             ("ours-sink", "ours-loan-source", "lt", env), ("ours-sink", "ours-source", "oz", zeromq_env),
             ("raw-pong", "raw-ping", "rl", env), ("ours-pong", "ours-ping", "ol", env))
    results: dict[str, dict[str, list]] = {tag: {"receiver": [], "sender": []} for *_, tag, _env in pairs}
    copies = []
    repeats = []
    try:
        for index in range(options.repeat):
            for receiver, sender, tag, pair_env in pairs:
                received, sent = _run_pair(receiver, sender, options, pair_env, folder, f"{tag}{index}")
                results[tag]["receiver"].append(received)
                results[tag]["sender"].append(sent)
            copies.append(_run_single("memcpy", options, env))
            if options.repeat > 1:
                single = argparse.Namespace(**{**vars(options), "repeat": 1})
                figures = {tag: _throughput_figures(results[tag]["sender"][-1], results[tag]["receiver"][-1], single)
                           for tag in ("rt", "ot", "lt", "oz")}
                times = {tag: _latency_figures(results[tag]["sender"][-1], results[tag]["receiver"][-1], single)
                         for tag in ("rl", "ol")}
                repeats.append({"throughput_ratio": figures["ot"]["mb_per_s"] / figures["rt"]["mb_per_s"],
                                "loaned_throughput_ratio": figures["lt"]["mb_per_s"] / figures["rt"]["mb_per_s"],
                                "zeromq_throughput_ratio": figures["oz"]["mb_per_s"] / figures["rt"]["mb_per_s"],
                                "memcpy_ratio": figures["ot"]["mb_per_s"] / _memcpy_figures([copies[-1]],
                                                                                             single)["mb_per_s"],
                                "latency_p50_ratio": times["ol"]["p50_us"] / times["rl"]["p50_us"],
                                "latency_p99_ratio": times["ol"]["p99_us"] / times["rl"]["p99_us"]})
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    pooled = {tag: {side: _pooled(values) for side, values in sides.items()} for tag, sides in results.items()}
    throughput = {name: _throughput_figures(pooled[tag]["sender"], pooled[tag]["receiver"], options)
                  for name, tag in (("ours", "ot"), ("raw", "rt"))}
    latency = {name: _latency_figures(pooled[tag]["sender"], pooled[tag]["receiver"], options)
               for name, tag in (("ours", "ol"), ("raw", "rl"))}
    zeromq = _throughput_figures(pooled["oz"]["sender"], pooled["oz"]["receiver"], options)
    loaned = _throughput_figures(pooled["lt"]["sender"], pooled["lt"]["receiver"], options)
    memcpy = _memcpy_figures(copies, options)
    throughput_ratio = throughput["ours"]["mb_per_s"] / throughput["raw"]["mb_per_s"]
    p50_ratio = latency["ours"]["p50_us"] / latency["raw"]["p50_us"]
    p99_ratio = latency["ours"]["p99_us"] / latency["raw"]["p99_us"]
    intact = all(entry["intact"] for part in (throughput, latency) for entry in part.values()) \
        and zeromq["intact"] and loaned["intact"] and memcpy["intact"]
    shared_ratio, memcpy_ratio = throughput_ratio, throughput["ours"]["mb_per_s"] / memcpy["mb_per_s"]
    return {
        "machine": machine(), "transport": "ipc", "size": options.size,
        "pinned": {"senders": pinned_cpus("ours-source"), "receivers": pinned_cpus("ours-sink")}
        if options.pin and pinned_cpus("ours-source") is not None else None,
        "throughput_ratio": throughput_ratio, "latency_p50_ratio": p50_ratio, "latency_p99_ratio": p99_ratio,
        "raw_throughput_mb_per_s": throughput["raw"]["mb_per_s"],
        "ours_throughput_mb_per_s": throughput["ours"]["mb_per_s"],
        "raw_latency_p50_us": latency["raw"]["p50_us"], "raw_latency_p99_us": latency["raw"]["p99_us"],
        "ours_latency_p50_us": latency["ours"]["p50_us"], "ours_latency_p99_us": latency["ours"]["p99_us"],
        "goals": {"throughput_ratio_min": THROUGHPUT_GOAL, "latency_ratio_max": LATENCY_GOAL,
                  "throughput_met": throughput_ratio >= THROUGHPUT_GOAL,
                  "latency_met": max(p50_ratio, p99_ratio) <= LATENCY_GOAL},
        "intact": intact, "repeat": options.repeat, "repeats": repeats,
        "throughput": {"message_bytes": int(np.prod(options.shape)), "shape": list(options.shape),
                       "messages_per_round": options.messages, "rounds": options.rounds, "window": options.window,
                       "warmup_messages": options.warmup_messages, **throughput},
        "latency": {"payload_bytes": PAYLOAD_BYTES, "round_trips_per_round": options.round_trips,
                    "rounds": options.rounds, "warmup_round_trips": options.warmup_round_trips, **latency},
        "shared_memory": {
            "shared_count": int(pooled["ot"]["sender"]["shared_count"]),
            "messages_sent": int(options.repeat * (options.rounds * options.messages + options.warmup_messages)),
            "throughput_ratio": shared_ratio,
            "zeromq_throughput_ratio": zeromq["mb_per_s"] / throughput["raw"]["mb_per_s"],
            "memcpy_ratio": memcpy_ratio,
            # the load-robust figures: bytes over the CPU time of both processes (sender + receiver, every thread)
            "cpu_throughput_ratio": throughput["ours"]["cpu_mb_per_s"] / throughput["raw"]["cpu_mb_per_s"],
            "cpu_memcpy_ratio": throughput["ours"]["cpu_mb_per_s"] / memcpy["cpu_mb_per_s"],
            "ours_zeromq": zeromq, "memcpy": memcpy,
            "goals": {"throughput_ratio_min": SHARED_THROUGHPUT_GOAL, "memcpy_ratio_min": MEMCPY_GOAL,
                      "throughput_met": shared_ratio >= SHARED_THROUGHPUT_GOAL,
                      "memcpy_met": memcpy_ratio >= MEMCPY_GOAL},
            "loaned": {**loaned, "shared_count": int(pooled["lt"]["sender"]["shared_count"]),
                       "gross": _gross_figures(pooled["lt"]["sender"], pooled["lt"]["receiver"], options),
                       "fill_us_per_message": pooled["lt"]["sender"]["fill_wall_s_per_message"] * 1e6,
                       "fill_cpu_us_per_message": pooled["lt"]["sender"]["fill_cpu_s_per_message"] * 1e6},
            "writers": {name: _writer_ratios(figures, throughput["raw"], memcpy) for name, figures in (
                ("publish", throughput["ours"]), ("loaned", loaned),
                ("loaned_with_fills", _gross_figures(pooled["lt"]["sender"], pooled["lt"]["receiver"], options)))},
        },
    }


def _memcpy_figures(results: list[dict], options) -> dict:
    nbytes = int(np.prod(options.shape))
    rates = [options.messages * nbytes / seconds / 1e6 for result in results for seconds in result["rounds_s"]]
    cpu_us = float(np.mean([result["cpu_s_per_message"] for result in results])) * 1e6
    return {"mb_per_s": float(np.median(rates)), "rounds_mb_per_s": rates, "cpu_us_per_message": cpu_us,
            "cpu_mb_per_s": nbytes / cpu_us, "intact": all(result["intact"] for result in results)}


def _gross_figures(sender: dict, receiver: dict, options) -> dict:
    """A loaned writer's figures with its fills in: MB/s (median of the rounds), the sender's CPU a message, and
    both processes' CPU a message and bytes per CPU second."""
    nbytes = int(np.prod(options.shape))
    rates = [options.messages * nbytes / seconds / 1e6 for seconds in sender["rounds_gross_s"]]
    cpu_us = sender["gross_cpu_s_per_message"] * 1e6 + receiver.get("cpu_us_per_message", float("nan"))
    return {"mb_per_s": float(np.median(rates)), "rounds_mb_per_s": rates,
            "sender_cpu_us_per_message": sender["gross_cpu_s_per_message"] * 1e6, "cpu_us_per_message": cpu_us,
            "cpu_mb_per_s": nbytes / cpu_us}


def _writer_ratios(figures: dict, raw: dict, memcpy: dict) -> dict:
    """One writer's ratios against raw pyzmq and the memcpy (wall and per CPU second), and whether it meets the
    transport goal (>= 3x raw pyzmq and within 2x of a memcpy, by wall time)."""
    ratios = {"throughput_ratio": figures["mb_per_s"] / raw["mb_per_s"],
              "memcpy_ratio": figures["mb_per_s"] / memcpy["mb_per_s"],
              "cpu_throughput_ratio": figures["cpu_mb_per_s"] / raw["cpu_mb_per_s"],
              "cpu_memcpy_ratio": figures["cpu_mb_per_s"] / memcpy["cpu_mb_per_s"]}
    ratios["goal_met"] = ratios["throughput_ratio"] >= SHARED_THROUGHPUT_GOAL and ratios["memcpy_ratio"] >= MEMCPY_GOAL
    return ratios


def _receiver_cpu(figures: dict) -> str:
    """The receiver's CPU a timed message: the whole process, and its receiving thread alone (no libzmq I/O thread)."""
    receiver = figures["receiver"]
    if "cpu_us_per_message" not in receiver:
        return "n/a"
    return (f"{receiver['cpu_us_per_message']:.0f} us/msg, "
            f"{receiver['main_thread_cpu_us_per_message']:.0f} in its thread")


def format_report(report: dict) -> str:
    t, lat, shm = report["throughput"], report["latency"], report["shared_memory"]
    pinned = report["pinned"]
    placement = f"senders on CPUs {pinned['senders']}, receivers on CPUs {pinned['receivers']}, " if pinned else ""
    shape = "x".join(str(n) for n in t["shape"])
    lines = [
        f"dptpu bench transport ({report['transport']}, {report['machine']['cores']} cores, "
        f"{placement}"
        f"pyzmq {report['machine']['pyzmq']}, libzmq {report['machine']['libzmq']})",
        f"(a) throughput, {shape} uint8 = {t['message_bytes']} bytes, {t['messages_per_round']} messages x "
        f"{t['rounds']} rounds, window {t['window']}",
        f"    raw pyzmq PUB/SUB : {t['raw']['mb_per_s']:9.1f} MB/s  ({t['raw']['messages_per_s']:.1f} msg/s, "
        f"sender CPU {t['raw']['sender_cpu_us_per_message']:.0f} us/msg, "
        f"receiver CPU {_receiver_cpu(t['raw'])})",
        f"    ours (graph)      : {t['ours']['mb_per_s']:9.1f} MB/s  ({t['ours']['messages_per_s']:.1f} msg/s, "
        f"sender CPU {t['ours']['sender_cpu_us_per_message']:.0f} us/msg, "
        f"receiver CPU {_receiver_cpu(t['ours'])})",
        f"    ours over ZeroMQ  : {shm['ours_zeromq']['mb_per_s']:9.1f} MB/s  (DPTPU_SHM=off, sender CPU "
        f"{shm['ours_zeromq']['sender_cpu_us_per_message']:.0f} us/msg, receiver CPU "
        f"{_receiver_cpu(shm['ours_zeromq'])})",
        f"    ours, loaned      : {shm['loaned']['mb_per_s']:9.1f} MB/s  (the writer fills a loaned segment; "
        f"fills not timed: {shm['loaned']['fill_us_per_message']:.0f} us/msg; with them "
        f"{shm['loaned']['gross']['mb_per_s']:.1f} MB/s; sender CPU "
        f"{shm['loaned']['sender_cpu_us_per_message']:.0f} us/msg, receiver CPU {_receiver_cpu(shm['loaned'])})",
        f"    memcpy            : {shm['memcpy']['mb_per_s']:9.1f} MB/s  (np.copyto, one process)",
        f"    throughput_ratio  : {report['throughput_ratio']:.3f}  (goal >= {THROUGHPUT_GOAL}; through shared "
        f"memory >= {SHARED_THROUGHPUT_GOAL}: {shm['shared_count']} of {shm['messages_sent']} messages were)",
        f"    over ZeroMQ / raw : {shm['zeromq_throughput_ratio']:.3f}   ours / memcpy: {shm['memcpy_ratio']:.3f}  "
        f"(goal >= {MEMCPY_GOAL})",
        f"    per CPU second    : raw {t['raw']['cpu_mb_per_s']:.0f}, ours {t['ours']['cpu_mb_per_s']:.0f}, "
        f"over ZeroMQ {shm['ours_zeromq']['cpu_mb_per_s']:.0f}, memcpy {shm['memcpy']['cpu_mb_per_s']:.0f} MB; "
        f"ours / raw "
        f"{shm['cpu_throughput_ratio']:.2f}, ours / memcpy {shm['cpu_memcpy_ratio']:.2f} (both processes' CPU)",
        *(f"    writer {name:<17}: {w['throughput_ratio']:.2f}x raw, {w['memcpy_ratio']:.2f} of a memcpy (per CPU "
          f"second {w['cpu_throughput_ratio']:.2f}x, {w['cpu_memcpy_ratio']:.2f}); goal >= {SHARED_THROUGHPUT_GOAL:g}x "
          f"raw and >= {MEMCPY_GOAL} of a memcpy: {'met' if w['goal_met'] else 'not met'}"
          for name, w in shm["writers"].items()),
        f"(b) round trip, {lat['payload_bytes']}-byte payload, {lat['ours']['round_trips']} round trips each",
        f"    raw pyzmq         : p50 {lat['raw']['p50_us']:8.1f} us  p99 {lat['raw']['p99_us']:8.1f} us",
        f"    ours (graph)      : p50 {lat['ours']['p50_us']:8.1f} us  p99 {lat['ours']['p99_us']:8.1f} us",
        f"    latency ratios    : p50 {report['latency_p50_ratio']:.2f}  p99 {report['latency_p99_ratio']:.2f}  "
        f"(goal <= {LATENCY_GOAL})",
        f"messages intact: {'yes' if report['intact'] else 'NO'}",
    ]
    return "\n".join(lines)


def run(args) -> int:
    """The ``dptpu bench transport`` entry: print the report; 0 when every message arrived intact, else 1."""
    report = measure(args)
    print(json.dumps(report, indent=2) if getattr(args, "json", False) else format_report(report))
    return 0 if report["intact"] else 1


def _child_main(options) -> int:
    if options.pin:  # set by the coordinator unless --no-pin
        cpus = pinned_cpus(options.role)
        if cpus is not None:
            os.sched_setaffinity(0, cpus)
    options.shape = tuple(int(n) for n in options.shape.split(","))
    result = ROLES[options.role](options)
    _emit(**result, cpu_s=time.process_time(), main_thread_cpu_s=time.thread_time(), wall_s=time.monotonic() - _STARTED)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The options of ``dptpu bench transport`` / ``python benchmarks/transport_bench.py`` (and of its children)."""
    parser = argparse.ArgumentParser(
        prog="dptpu bench transport", description=__doc__.split("\n\n")[0],
        epilog="Two processes over ipc, ours (dptpu.graph publisher -> subscription) and raw pyzmq side by side; "
               "ratios are ours / raw (see docs/benchmarks.md).")
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--size", choices=tuple(SIZES), default="full",
                        help="full: 24x480x640 (default); small: 2x48x64 and few messages (for tests)")
    parser.add_argument("--messages", type=int, default=None, help="timed messages per round (default 100)")
    parser.add_argument("--rounds", type=int, default=None, help="rounds of each measurement (default 3)")
    parser.add_argument("--round-trips", type=int, default=None, help="timed round trips per round (default 2000)")
    parser.add_argument("--window", type=int, default=None, help=f"messages in flight (default {DEFAULT_WINDOW})")
    parser.add_argument("--repeat", type=int, default=None,
                        help="run raw and ours alternately this many times, fresh processes each time; the report "
                             "pools them and lists each repeat's ratios (default 1)")
    parser.add_argument("--no-pin", action="store_true",
                        help="let the OS place the processes (default: senders on the first half of the CPUs, "
                             "receivers on the second half)")
    parser.add_argument("--pin", action="store_true", help=argparse.SUPPRESS)  # a child's own pinning
    parser.add_argument("--role", choices=tuple(ROLES), default=None, help=argparse.SUPPRESS)
    for name in ("--shape", "--ack", "--data"):
        parser.add_argument(name, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--warmup-messages", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--warmup-round-trips", type=int, default=None, help=argparse.SUPPRESS)
    return parser


def main(argv=None) -> int:
    """Entry of ``dptpu bench transport ARGS`` and of ``python benchmarks/transport_bench.py ARGS``.

    Returns 0 when every message arrived intact, 1 when not, 2 for a bad option (message on stderr).
    """
    parsed = build_parser().parse_args(argv)
    if parsed.role:
        return _child_main(parsed)
    try:
        return run(parsed)
    except ValueError as exc:
        print(f"dptpu bench transport: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
