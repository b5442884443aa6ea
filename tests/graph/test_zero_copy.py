"""Large arrays travel without copies: received arrays are read-only views of the received frames."""

from __future__ import annotations

import time

import numpy as np
import zmq

from dptpu.graph import Node, SingleThreadedExecutor
from dptpu.messages import Image


def test_image_arrives_bit_exact_as_read_only_view_of_the_frame(context):
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
