"""Test node for the shared-memory path: publishes every large message type, or subscribes to them.

``--role pub``: one publisher per topic of :func:`large_messages`; waits for ``--wait-subs`` subscriptions on
each, publishes ``--count`` rounds (round ``r`` is ``large_messages(r)``, ``--period`` s apart), prints
``{"event": "published", "shared": {topic: shared_count}, "published": {topic: published_count}}``, lingers.
``--role sub``: subscribes to every topic and prints ``{"event": "received", "topic", "round", "equal",
"shared"}`` per message (``equal``: bit for bit the message of that round, checked after ``--delay`` s).
Prints ``{"event": "ready"}`` first.
"""

import argparse
import json
import mmap
import sys
import time

import numpy as np

import dptpu.graph as rclpy
from dptpu.messages import AbsolutePhase, FringeFrame, Image, PhaseMaps, PointCloud2, Trigger, encode
from dptpu.messages.std import Header, Time

HEIGHT, WIDTH = 480, 640


def large_messages(round_index: int) -> dict:
    """``{topic: message}``: a FringeFrame, PhaseMaps, AbsolutePhase, PointCloud2, depth and mono16 Image of
    640x480, seeded by ``round_index`` (so every process makes the same ones)."""
    rng = np.random.default_rng(round_index)
    header = Header(stamp=Time(sec=round_index), frame_id="scanner_optical_frame")
    phases = rng.uniform(0, 2 * np.pi, (2, HEIGHT, WIDTH)).astype(np.float32)
    cloud = rng.normal(size=(HEIGHT, WIDTH, 5)).astype(np.float32)
    cloud[rng.random((HEIGHT, WIDTH)) < 0.1] = np.nan
    return {
        "/shm/frame": FringeFrame(image=Image.from_array(rng.integers(0, 256, (HEIGHT, WIDTH), dtype=np.uint8),
                                                         "mono8", header=header),
                                  trigger=Trigger(sequence_id=round_index, pattern_index=3, frequency=64.0, step=3)),
        "/shm/phase": PhaseMaps(header=header, sequence_id=round_index, frequencies=np.array([64.0, 1.0]),
                                phases=phases, modulation=rng.uniform(0, 90, phases.shape).astype(np.float32),
                                valid=rng.random((HEIGHT, WIDTH)) < 0.9),
        "/shm/absolute": AbsolutePhase(header=header, sequence_id=round_index, frequency=64.0,
                                       absolute_phase=rng.uniform(0, 400, (HEIGHT, WIDTH)).astype(np.float32),
                                       fringe_order=rng.integers(0, 64, (HEIGHT, WIDTH), dtype=np.int32),
                                       valid=rng.random((HEIGHT, WIDTH)) < 0.9,
                                       reliability=rng.random((HEIGHT, WIDTH), dtype=np.float32), method="mf"),
        "/shm/points": PointCloud2.from_array(cloud, ("x", "y", "z", "intensity", "confidence"), header=header),
        "/shm/depth": Image.from_array(cloud[..., 2].copy(), "32FC1", header=header),
        "/shm/mono16": Image.from_array(rng.integers(0, 4096, (HEIGHT, WIDTH), dtype=np.uint16), "mono16",
                                       header=header),
    }


def same_message(topic: str, a, b) -> bool:
    """Bit for bit the same encoded message (NaN payloads included)."""
    return all(bytes(x) == bytes(y) for x, y in zip(encode(topic, a), encode(topic, b), strict=True))


def round_of(msg) -> int:
    """The round a message of :func:`large_messages` belongs to (its header's seconds)."""
    return int((msg.image.header if isinstance(msg, FringeFrame) else msg.header).stamp.sec)


def is_shared(array: np.ndarray) -> bool:
    """Whether ``array`` views a shared-memory segment (its bases end in an ``mmap``), not a ZeroMQ frame."""
    base = array
    for _ in range(16):
        if isinstance(base, mmap.mmap):
            return True
        if isinstance(base, np.ndarray):
            base = base.base
        elif isinstance(base, memoryview):
            base = base.obj
        else:
            return False
    return False


def first_array(msg) -> np.ndarray:
    if isinstance(msg, FringeFrame):
        return msg.image.data
    for name in ("phases", "absolute_phase", "data"):
        if hasattr(msg, name):
            return getattr(msg, name)
    raise TypeError(type(msg).__name__)


def emit(**event):
    print(json.dumps(event), flush=True)


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = argparse.ArgumentParser()
    parser.add_argument("--role", choices=("pub", "sub"), required=True)
    parser.add_argument("--count", type=int, default=1)
    parser.add_argument("--period", type=float, default=0.0)
    parser.add_argument("--wait-subs", type=int, default=1)
    parser.add_argument("--linger", type=float, default=30.0)
    parser.add_argument("--delay", type=float, default=0.0, help="sub: seconds each callback takes (a slow one)")
    options = parser.parse_args(rclpy.remove_ros_args(argv)[1:])
    rclpy.init(args=argv)
    node = rclpy.create_node(f"shm_{options.role}")
    kinds = {topic: type(msg) for topic, msg in large_messages(0).items()}
    try:
        if options.role == "pub":
            publishers = {topic: node.create_publisher(kind, topic, 10) for topic, kind in kinds.items()}
            emit(event="ready")
            for publisher in publishers.values():
                if not publisher.wait_for_subscriptions(options.wait_subs, timeout_sec=20.0):
                    emit(event="error", reason=f"no subscription on {publisher.topic_name}")
                    return 1
            for round_index in range(options.count):
                for topic, msg in large_messages(round_index).items():
                    publishers[topic].publish(msg)
                time.sleep(options.period)
            emit(event="published", shared={t: p.shared_count for t, p in publishers.items()},
                 published={t: p.published_count for t, p in publishers.items()})
        else:
            expected: dict = {}

            def on_message(topic, msg):
                time.sleep(options.delay)  # a slow subscriber: the publisher goes on writing meanwhile
                index = round_of(msg)
                if index not in expected:
                    expected[index] = large_messages(index)
                emit(event="received", topic=topic, round=index, equal=same_message(topic, expected[index][topic], msg),
                     shared=is_shared(first_array(msg)))

            for topic, kind in kinds.items():
                node.create_subscription(kind, topic, lambda msg, t=topic: on_message(t, msg), 10)
            emit(event="ready")
        end = time.monotonic() + options.linger
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
    except KeyboardInterrupt:
        pass
    finally:
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
