"""Test node: a subscriber that keeps every image it gets, under a low file-descriptor limit (``--nofile N``).

Subscribes to ``/limits/image`` with a KEEP_ALL queue (a recorder behind its stream holds every message, and each
message through shared memory holds its segment mapped: two descriptors), prints ``{"event": "ready"}``, then, once
``--count`` messages arrived or ``--timeout`` s passed, ``{"event": "done", "received": [index, ...], "intact": n,
"shared": n, "lost_count": n}`` (``intact``: bit for bit the publisher's :func:`image_of`, checked at the end, when
every message is still held).
"""

import argparse
import json
import resource
import sys
import time

import dptpu.graph as rclpy
from dptpu.graph.qos import HistoryPolicy, QoSProfile
from dptpu.messages import Image
from tests.graph.nodes.shm_limited_publisher import TOPIC, image_of
from tests.graph.nodes.shm_peer import is_shared


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = argparse.ArgumentParser()
    parser.add_argument("--nofile", type=int, default=0)
    parser.add_argument("--count", type=int, default=10)
    parser.add_argument("--timeout", type=float, default=60.0)
    options = parser.parse_args(rclpy.remove_ros_args(argv)[1:])
    if options.nofile:
        resource.setrlimit(resource.RLIMIT_NOFILE, (options.nofile, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
    rclpy.init(args=argv)
    node = rclpy.create_node("limited_subscriber")
    kept: list = []
    subscription = node.create_subscription(Image, TOPIC, kept.append, QoSProfile(history=HistoryPolicy.KEEP_ALL))
    print(json.dumps({"event": "ready"}), flush=True)
    end = time.monotonic() + options.timeout
    while len(kept) < options.count and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    intact = sum(bool((msg.to_array() == image_of(int(msg.header.frame_id))).all()) for msg in kept)
    print(json.dumps({"event": "done", "received": [int(msg.header.frame_id) for msg in kept], "intact": intact,
                      "shared": sum(is_shared(msg.data) for msg in kept), "lost_count": subscription.lost_count}),
          flush=True)
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
