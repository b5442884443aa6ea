"""Large arrays travel without copies: received arrays are read-only views of the received frames."""

from __future__ import annotations

import time

import numpy as np
import zmq

from dptpu.graph import Node, SingleThreadedExecutor
from dptpu.messages import Image


def test_image_arrives_bit_exact_as_read_only_view_of_the_frame(context, monkeypatch):
    monkeypatch.setenv("DPTPU_SHM", "off")  # the ZeroMQ path (shared memory: tests/graph/test_shared_memory*.py)
    node = Node("camera", context=context)
    received = []
    node.create_subscription(Image, "image_raw", received.append, 10)
    publisher = node.create_publisher(Image, "image_raw", 10)
    assert publisher.wait_for_subscriptions(1, timeout_sec=3.0)
    pixels = np.random.default_rng(0).integers(0, 4096, size=(480, 640), dtype=np.uint16)  # 600 KiB
    publisher.publish(Image.from_array(pixels, "mono16"))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + 3.0
    while not received and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    image = received[0]
    out = image.to_array()
    assert out.shape == (480, 640) and np.array_equal(out, pixels)
    assert not image.data.flags.writeable and not image.data.flags.owndata
    base = image.data
    while isinstance(base, np.ndarray) and base.base is not None:
        base = base.base
    assert isinstance(base, memoryview) and isinstance(base.obj, zmq.Frame)  # a view of the ZeroMQ frame itself


def test_raw_subscription_to_any_type_gets_the_undecoded_frames(context):
    from dptpu.graph import String
    from dptpu.messages import decode

    node = Node("recorder", context=context)
    frames_seen = []
    node.create_subscription(None, "/anything", frames_seen.append, 10, raw=True)
    publisher = node.create_publisher(String, "/anything", 10)
    assert publisher.wait_for_subscriptions(1, timeout_sec=3.0)
    publisher.publish(String(data="as bytes"))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + 3.0
    while not frames_seen and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    frames = frames_seen[0]
    assert all(isinstance(f, memoryview) for f in frames) and bytes(frames[0]) == b"/anything"
    assert decode(frames) == ("/anything", String(data="as bytes"))
    graph_types = dict(node.get_topic_names_and_types())
    assert graph_types["/anything"] == ["std_msgs/msg/String"]


def _stack_type():
    from dptpu.messages.registry import is_registered, lookup
    from dptpu.messages.schema import Message, array, message, scalar

    if is_registered("dptpu_test/msg/FrameStack"):
        return lookup("dptpu_test/msg/FrameStack")

    @message("dptpu_test/msg/FrameStack", version=1)
    class FrameStack(Message):
        seq: int = scalar("uint64")
        frames: np.ndarray = array("uint8", ("F", "H", "W"))

    return FrameStack


def test_a_large_message_is_copied_by_neither_side(context):
    """tracemalloc sees every numpy and Python allocation (not ZeroMQ's own buffers): publishing and taking
    a 24x120x160 (460,800-byte) stack must allocate far less than one copy of it, on either side."""
    import tracemalloc

    stack_type = _stack_type()
    node = Node("zero_copy", context=context)
    received = []
    node.create_subscription(stack_type, "stack", received.append, 10)
    publisher = node.create_publisher(stack_type, "stack", 10)
    assert publisher.wait_for_subscriptions(1, timeout_sec=3.0)
    frames = np.random.default_rng(1).integers(0, 256, size=(24, 120, 160), dtype=np.uint8)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    peaks = {"publish": [], "receive": []}
    for seq in range(3):  # the first round also warms up (imports, caches)
        message = stack_type(seq=seq, frames=frames)
        tracemalloc.start()
        publisher.publish(message)
        peaks["publish"].append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        deadline = time.monotonic() + 3.0
        tracemalloc.start()
        while len(received) <= seq and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        peaks["receive"].append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert [msg.seq for msg in received] == [0, 1, 2] and np.array_equal(received[-1].frames, frames)
    # measured: publish 1.6 KB, receive 3.6-6.2 KB per message after the first; one copy would be 460,800 bytes
    assert max(peaks["publish"][1:]) < 64_000 and max(peaks["receive"][1:]) < 64_000, peaks
