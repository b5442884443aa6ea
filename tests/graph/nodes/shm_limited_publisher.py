"""Test node: a publisher of large images run under a machine's limits (the shared-memory path's hostile cases).

``--nofile N`` lowers this process's soft file-descriptor limit to ``N`` before the graph starts;
``--undumpable`` makes it not dumpable (``prctl(PR_SET_DUMPABLE, 0)``, what a process that changed its user or
runs with file capabilities is). It waits for ``--wait-subs`` subscriptions on ``/limits/image``, publishes
``--count`` mono8 images of :data:`SHAPE` (image ``i`` is :func:`image_of` ``(i)``), ``--period`` s apart, and prints
``{"event": "published", "published", "shared", "full", "errors", "most_fds", "segments", "pool_bytes"}``: ``errors``
lists what ``publish`` raised, ``most_fds`` the most descriptors the process had open after a publish, ``segments``
and ``pool_bytes`` its pool's at the end. Prints ``{"event": "ready"}`` first.
"""

import argparse
import ctypes
import json
import os
import resource
import sys
import time

import numpy as np

import dptpu.graph as rclpy
from dptpu.messages import Image
from dptpu.messages.std import Header

SHAPE = (256, 400)  # 100 kB: above DPTPU_SHM_MIN_BYTES
TOPIC = "/limits/image"


def image_of(index: int) -> np.ndarray:
    """The pixels of image ``index`` (a different pattern each)."""
    return np.random.default_rng(index).integers(0, 256, SHAPE, dtype=np.uint8)


def emit(**event):
    print(json.dumps(event), flush=True)


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = argparse.ArgumentParser()
    parser.add_argument("--nofile", type=int, default=0)
    parser.add_argument("--undumpable", action="store_true")
    parser.add_argument("--count", type=int, default=10)
    parser.add_argument("--period", type=float, default=0.0)
    parser.add_argument("--wait-subs", type=int, default=1)
    parser.add_argument("--linger", type=float, default=5.0)
    options = parser.parse_args(rclpy.remove_ros_args(argv)[1:])
    if options.nofile:
        resource.setrlimit(resource.RLIMIT_NOFILE, (options.nofile, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
    if options.undumpable:
        ctypes.CDLL(None).prctl(4, 0, 0, 0, 0)  # PR_SET_DUMPABLE, 0
    rclpy.init(args=argv)
    node = rclpy.create_node("limited_publisher")
    publisher = node.create_publisher(Image, TOPIC, 10)
    emit(event="ready")
    if not publisher.wait_for_subscriptions(options.wait_subs, timeout_sec=30.0):
        emit(event="error", reason=f"no subscription on {TOPIC}")
        return 1
    errors, most_fds = [], 0
    for index in range(options.count):
        try:
            publisher.publish(Image.from_array(image_of(index), "mono8", header=Header(frame_id=str(index))))
        except Exception as exc:  # noqa: BLE001 -- the test wants to see what publish raised, if anything
            errors.append(f"{type(exc).__name__}: {exc}")
        most_fds = max(most_fds, len(os.listdir("/proc/self/fd")))
        time.sleep(options.period)
    pool = publisher._pool
    emit(event="published", published=publisher.published_count, shared=publisher.shared_count,
         full=pool.full_count if pool is not None else None, errors=errors, most_fds=most_fds,
         segments=pool.segment_count if pool is not None else None,
         pool_bytes=pool.pool_bytes if pool is not None else None)
    end = time.monotonic() + options.linger
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
