"""The graph's receive path, CPU a frame: what a node pays to take a camera frame off the graph (issue 20).

Run it as ``dptpu bench receive_path [--size 640x480] [--bursts 60] [--json]`` (or
``python benchmarks/receive_path_bench.py``). Not a test: nothing asserts a time.

Two processes on one host, shared memory on (as the sim and the phase node): a publisher process sends bursts of
24 ``FringeFrame`` messages (a 2 x 12-step scan, mono8 random frames), one burst every 40 ms; this process's node
takes them with a ``SingleThreadedExecutor`` (best effort, depth 100, as the phase node) and holds the last 24
frames' arrays alive, as the phase node holds a scan's frames while it assembles them, so every frame's segment is
mapped, picked up, decoded, let go and released as in the graph. The callback does nothing else, so the figures
are the graph's own cost a frame (the receive, the shared-memory pickup and release, the queue, the executor, the
decode), not the phase math:

- ``main_us_per_frame``: this process's main thread (``time.thread_time``), from the end of the third burst to the
  last frame, over the frames received in between;
- ``process_us_per_frame``: the same for the whole process (``time.process_time``: also the runtime's I/O thread
  and libzmq's);
- ``frames``, ``lost``, ``dropped``: frames timed, the subscription's ``lost_count`` and ``queue_dropped_count``.

Compare two trees by running each from its own ``PYTHONPATH`` in alternation on one machine (docs/benchmarks.md,
Run 14).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

FRAMES_PER_BURST = 24
BURST_PERIOD_S = 0.04
WARMUP_BURSTS = 3
DOMAIN_ID = 71
QOS_DEPTH = 100
_TOPIC = "/camera/image_raw"


def _qos():
    from dptpu.graph.qos import QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=QOS_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)


def _publish_bursts(folder: str, size: tuple[int, int], bursts: int) -> None:
    """The publisher process: wait for the subscriber, then ``bursts + WARMUP_BURSTS`` bursts of a scan's frames."""
    os.environ["DPTPU_DISCOVERY_DIR"] = folder
    from dptpu.graph.context import Context
    from dptpu.graph.node import Node
    from dptpu.messages import FringeFrame
    from dptpu.nodes.harness import fringe_frames

    context = Context()
    context.init([], domain_id=DOMAIN_ID)
    try:
        publisher = Node("receive_path_camera", context=context).create_publisher(FringeFrame, _TOPIC, _qos())
        width, height = size
        rng = np.random.default_rng(0)
        stacks = [rng.integers(0, 255, (FRAMES_PER_BURST // 2, height, width), dtype=np.uint8) for _ in range(2)]
        if not publisher.wait_for_subscriptions(1, timeout_sec=30.0):
            return
        time.sleep(1.0)  # the subscriber's shared-memory subscription reaches the publisher too
        for burst in range(bursts + WARMUP_BURSTS):
            for frame in fringe_frames(stacks, (64.0, 1.0), sequence_id=burst + 1):
                publisher.publish(frame)
            time.sleep(BURST_PERIOD_S)
        time.sleep(0.5)
    finally:
        context.shutdown()


def receive_path(size: tuple[int, int], bursts: int) -> dict:
    """Time this process's taking of ``bursts`` bursts of frames (the module docstring's figures)."""
    from dptpu.graph.context import Context
    from dptpu.graph.executors import SingleThreadedExecutor
    from dptpu.graph.node import Node
    from dptpu.messages import FringeFrame
    from dptpu.nodes.node_main import keep_freed_memory

    keep_freed_memory()  # as every node does
    folder = tempfile.mkdtemp(prefix="drp", dir="/tmp")  # short: ipc socket paths must fit
    saved = os.environ.get("DPTPU_DISCOVERY_DIR")
    os.environ["DPTPU_DISCOVERY_DIR"] = folder
    context = Context()
    publisher = None
    try:
        context.init([], domain_id=DOMAIN_ID)
        node = Node("receive_path", context=context)
        held: list = []
        count = [0]

        def on_frame(msg) -> None:  # hold the scan's frames, as the phase node does while it assembles them
            held.append(msg.image.to_array())
            if len(held) > FRAMES_PER_BURST:
                del held[0]
            count[0] += 1

        subscription = node.create_subscription(FringeFrame, _TOPIC, on_frame, _qos())
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        # the publisher: this file in a process of its own (the graph's nodes are processes)
        publisher = subprocess.Popen([sys.executable, __file__, "--publish-into", folder, "--size",
                                      f"{size[0]}x{size[1]}", "--bursts", str(bursts)], stdin=subprocess.DEVNULL)
        total = (bursts + WARMUP_BURSTS) * FRAMES_PER_BURST
        start = None
        deadline = time.monotonic() + 60.0 + bursts * BURST_PERIOD_S * 4
        while count[0] < total and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
            if start is None and count[0] >= WARMUP_BURSTS * FRAMES_PER_BURST:
                start = (count[0], time.thread_time(), time.process_time())
            if publisher.poll() is not None and count[0] < total:
                executor.spin_once(timeout_sec=0.5)  # what was still on the way
                break
        end = (count[0], time.thread_time(), time.process_time())
        executor.shutdown()
        if start is None or end[0] <= start[0]:
            raise RuntimeError(f"only {count[0]} of {total} frames arrived (lost {subscription.lost_count}, "
                               f"dropped {subscription.queue_dropped_count})")
        frames = end[0] - start[0]
        return {"frames": frames, "main_us_per_frame": round(1e6 * (end[1] - start[1]) / frames, 1),
                "process_us_per_frame": round(1e6 * (end[2] - start[2]) / frames, 1),
                "lost": subscription.lost_count, "dropped": subscription.queue_dropped_count,
                "shared_memory": context._runtime().transport.shared_memory is not None}
    finally:
        context.try_shutdown()
        if publisher is not None:
            try:
                publisher.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                publisher.kill()
                publisher.wait()
        if saved is None:
            os.environ.pop("DPTPU_DISCOVERY_DIR", None)
        else:
            os.environ["DPTPU_DISCOVERY_DIR"] = saved
        shutil.rmtree(folder, ignore_errors=True)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dptpu bench receive_path", description=__doc__.split("\n")[0])
    parser.add_argument("--size", default="640x480", help="frame size WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--bursts", type=int, default=60, help="timed bursts of 24 frames (default 60)")
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--publish-into", default=None, help=argparse.SUPPRESS)  # the publisher process's own run
    return parser


def main(argv=None) -> int:
    """``dptpu bench receive_path ARGS``; the exit code (2 for bad options)."""
    args = build_parser().parse_args(argv)
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        width = height = 0
    if width < 1 or height < 1 or args.bursts < 1:
        print(f"dptpu bench receive_path: error: --size must be WIDTHxHEIGHT and --bursts >= 1; got {args.size!r}, "
              f"{args.bursts}", file=sys.stderr)
        return 2
    if args.publish_into:
        _publish_bursts(args.publish_into, (width, height), args.bursts)
        return 0
    report = {"benchmark": "receive_path", "size": f"{width}x{height}", "bursts": args.bursts,
              "load_average": list(os.getloadavg()), **receive_path((width, height), args.bursts)}
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"{report['frames']} frames of {report['size']}: main thread {report['main_us_per_frame']} us a frame, "
              f"process {report['process_us_per_frame']} us (lost {report['lost']}, dropped {report['dropped']}, "
              f"shared memory {report['shared_memory']})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
