"""Test node: publishes ``String(data=f"{prefix}{i}")`` for i = 0..count-1, then lingers.

Prints JSON lines on stdout: ``{"event": "ready", "topic": ..., "endpoints": [...]}`` once the publisher exists,
``{"event": "published", "count": n}`` when done. Options come before ``--ros-args``.
"""

import argparse
import json
import sys
import time

import dptpu.graph as rclpy
from dptpu.graph import DurabilityPolicy, QoSProfile, ReliabilityPolicy, String


def emit(**event):
    print(json.dumps(event), flush=True)


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", default="talker")
    parser.add_argument("--topic", default="chatter")
    parser.add_argument("--prefix", default="")
    parser.add_argument("--count", type=int, default=5)
    parser.add_argument("--period", type=float, default=0.0, help="seconds between messages")
    parser.add_argument("--depth", type=int, default=10)
    parser.add_argument("--best-effort", action="store_true")
    parser.add_argument("--transient-local", action="store_true")
    parser.add_argument("--wait-subs", type=int, default=0, help="wait for this many subscriptions first")
    parser.add_argument("--linger", type=float, default=0.5, help="seconds to stay alive after publishing")
    options = parser.parse_args(rclpy.remove_ros_args(argv)[1:])
    rclpy.init(args=argv)
    node = rclpy.create_node(options.name)
    qos = QoSProfile(depth=options.depth,
                     reliability=ReliabilityPolicy.BEST_EFFORT if options.best_effort else ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL if options.transient_local
                     else DurabilityPolicy.VOLATILE)
    publisher = node.create_publisher(String, options.topic, qos)
    emit(event="ready", topic=publisher.topic_name, endpoints=publisher.endpoints)
    try:
        if options.wait_subs and not publisher.wait_for_subscriptions(options.wait_subs, timeout_sec=10.0):
            emit(event="error", reason="subscriptions did not connect")
            return 1
        start = time.monotonic()
        for index in range(options.count):
            publisher.publish(String(data=f"{options.prefix}{index}"))
            if options.period:
                time.sleep(max(0.0, start + (index + 1) * options.period - time.monotonic()))
        emit(event="published", count=publisher.published_count)
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
