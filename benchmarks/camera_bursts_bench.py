"""The camera node's CPU a frame with and without ``frame_bursts``, on the shipped viky.cti producer (issue 20).

Run it as ``dptpu bench camera_bursts [--size 640x480] [--rate 200] [--steps 12] [--seconds 3] [--rounds 4]
[--pairs 3] [--json]`` (or ``python benchmarks/camera_bursts_bench.py``). Not a test: nothing asserts a time.

Each run starts the camera node as its own process (viky, free-running at ``--rate`` frames/s, Mono8 at ``--size``),
either ``frames`` (``frame_bursts:=false``: a FringeFrame a Trigger) or ``bursts`` (``frame_bursts:=true``: a
FringeBurst an entry), with this process subscribed to what it publishes (another process: shared memory on, the
node's default threshold). The node's CPU (user + system, every thread, ``/proc/<pid>/stat``) is read over
``--rounds`` pairs of windows of ``--seconds`` each:

- ``idle``: no Triggers; the node fetches every frame of the producer and lets it go (the floor of its rate);
- ``scans``: back-to-back two-frequency scans of ``--steps`` steps, one Trigger every two frame periods, so that
  every Trigger meets a frame (about half the frames are claimed).

Two figures a frame published (in a burst or alone), each in ``--pairs`` alternating runs of each variant (the report
gives every run and the medians):

- ``us_per_frame``: the node's process CPU in a round's scans window above its idle window's rate, per frame; the
  median of a run's rounds. Every thread counts (viky's rendering, the ZeroMQ I/O thread), so the idle floor is
  large (viky makes and the node copies every frame) and the figure spreads wide on a busy machine;
- ``handling_us_per_frame``: the thread CPU (``time.thread_time``) the node spends in what the variants do
  differently, per frame a Trigger claimed: choosing the frame's destination before its copy out of the producer's
  buffer (a loaned single frame, or its burst's row) and ``on_frame`` (a FringeFrame published, or the frame joined
  to its burst and the burst published). The node runs in this module's ``--child`` mode, which times those two
  methods of ``CameraNode`` and prints the totals at exit; the copy itself (the same in both) is not in it.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from dptpu.graph import Context, Node
from dptpu.graph.executors import SingleThreadedExecutor
from dptpu.messages import FringeBurst, FringeFrame, Trigger
from dptpu.nodes.camera.node import CameraNode
from dptpu.nodes.node_main import run_node

REPO_ROOT = Path(__file__).resolve().parents[1]
DOMAIN_ID = 96
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
#: The ``--child`` node's line at exit: this prefix, then JSON.
CHILD_TOTALS = "camera_bursts_child: "


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far (every thread)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def scan_triggers(sequence_id: int, steps: int):
    """A two-frequency scan's Triggers (64 and 1 periods, ``steps`` each)."""
    return [Trigger(sequence_id=sequence_id, pattern_index=entry * steps + step, pattern_count=2 * steps,
                    frequency=frequency, steps=steps, step=step)
            for entry, frequency in enumerate((64.0, 1.0)) for step in range(steps)]


class _Counter:
    def __init__(self, frames_of):
        self.frames = 0
        self._frames_of = frames_of
        self._lock = threading.Lock()

    def __call__(self, msg) -> None:
        with self._lock:
            self.frames += self._frames_of(msg)


def _read_lines(stream, lines: list[str]) -> None:
    for line in stream:
        lines.append(line)


def run_once(*, bursts: bool, size: str, rate: float, steps: int, seconds: float, rounds_count: int) -> dict:
    """One run of the camera node (module docstring): ``{"idle_cpu_s_per_s", "triggers", "rounds_us_per_frame",
    "us_per_frame"}``."""
    width, height = (int(v) for v in size.lower().split("x"))
    folder = Path(tempfile.mkdtemp(prefix="dcb", dir="/tmp"))
    graph_env = {"DPTPU_DISCOVERY_DIR": str(folder / "d"), "DPTPU_DOMAIN_ID": str(DOMAIN_ID)}  # a private graph
    previous = {name: os.environ.get(name) for name in graph_env}
    os.environ.update(graph_env)  # this process's Context reads them
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    command = [sys.executable, __file__, "--child", "--ros-args", "-p", "trigger_mode:=free-running",
               "-p", f"frame_rate_hz:={float(rate)}", "-p", f"width:={width}", "-p", f"height:={height}",
               "-p", f"frame_bursts:={str(bursts).lower()}", "-p", "frame_timeout_s:=0.5"]
    node = subprocess.Popen(command, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    threading.Thread(target=_read_lines, args=(node.stderr, lines), daemon=True).start()
    context = Context()
    context.init([], domain_id=DOMAIN_ID)
    probe = Node("camera_bench", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(probe)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        if bursts:
            counter = _Counter(lambda msg: len(msg.triggers))
            subscription = probe.create_subscription(FringeBurst, "/camera/frame_bursts", counter, 100)
        else:
            counter = _Counter(lambda msg: 1)
            subscription = probe.create_subscription(FringeFrame, "/camera/image_raw", counter, 100)
        triggers = probe.create_publisher(Trigger, "/projector/trigger", 100)
        deadline = time.monotonic() + 30
        while not (triggers.get_subscription_count() and subscription.get_publisher_count()
                   and any("trigger mode free-running" in line for line in lines)):
            if time.monotonic() > deadline or node.poll() is not None:
                raise RuntimeError(f"the camera node did not start: {''.join(lines)[-2000:]}")
            time.sleep(0.05)
        time.sleep(1.0)  # the node's links settle; the allocator warms up
        rounds, idle_rates, sequence_id, sent_total = [], [], 0, 0
        for _ in range(rounds_count):
            start, cpu0 = time.monotonic(), cpu_s(node.pid)
            time.sleep(seconds)
            idle_rate = (cpu_s(node.pid) - cpu0) / (time.monotonic() - start)
            frames0, sent = counter.frames, 0
            start, cpu0 = time.monotonic(), cpu_s(node.pid)
            while time.monotonic() - start < seconds:
                sequence_id += 1
                for trigger in scan_triggers(sequence_id, steps):
                    triggers.publish(trigger)
                    sent += 1
                    time.sleep(2.0 / rate)  # two frame periods: every Trigger meets a frame
            time.sleep(0.3)  # the last scan's frames and burst go out
            cpu1, end = cpu_s(node.pid), time.monotonic()
            frames = counter.frames - frames0
            if frames < 0.9 * sent:
                raise RuntimeError(f"only {frames} of {sent} Triggers got their frame: lower --rate")
            rounds.append(((cpu1 - cpu0) - idle_rate * (end - start)) / frames * 1e6)
            idle_rates.append(idle_rate)
            sent_total += sent
        result = {"idle_cpu_s_per_s": round(float(np.median(idle_rates)), 4), "triggers": sent_total,
                  "rounds_us_per_frame": [round(v, 1) for v in rounds],
                  "us_per_frame": round(float(np.median(rounds)), 1)}
        node.terminate()
        out, _ = node.communicate(timeout=20)
        totals = json.loads(next(line for line in out.splitlines() if line.startswith(CHILD_TOTALS))
                            [len(CHILD_TOTALS):])
        per_frame_us = {name: totals[f"{name}_s"] / max(totals["frames"], 1) * 1e6
                        for name in ("destination", "on_frame")}
        result["handling_us_per_frame"] = round(sum(per_frame_us.values()), 1)
        result.update({f"{name}_us_per_frame": round(value, 1) for name, value in per_frame_us.items()})
        return result
    finally:
        if node.poll() is None:
            node.kill()
            node.wait()
        executor.shutdown(timeout_sec=2.0)
        context.try_shutdown()
        spinner.join(timeout=2.0)
        shutil.rmtree(folder, ignore_errors=True)
        for name, value in previous.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def child(argv: list[str]) -> int:
    """The camera node, timing its destination choice and ``on_frame`` for frames with a Trigger (thread CPU)."""
    totals = {"frames": 0, "destination_s": 0.0, "on_frame_s": 0.0}
    destination, on_frame = CameraNode._frame_destination, CameraNode.on_frame

    def timed_destination(self, shape, dtype, trigger):
        start = time.thread_time()
        try:
            return destination(self, shape, dtype, trigger)
        finally:
            if trigger is not None:
                totals["destination_s"] += time.thread_time() - start

    def timed_on_frame(self, frame, stamp_ns, trigger):
        start = time.thread_time()
        on_frame(self, frame, stamp_ns, trigger)
        if trigger is not None:
            totals["on_frame_s"] += time.thread_time() - start
            totals["frames"] += 1

    CameraNode._frame_destination = timed_destination  # type: ignore[method-assign]
    CameraNode.on_frame = timed_on_frame  # type: ignore[method-assign]
    return run_node("camera", CameraNode, ["camera", *argv],
                    on_exit=lambda node: print(CHILD_TOTALS + json.dumps(totals), flush=True))


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--child"]:
        return child(argv[1:])
    parser = argparse.ArgumentParser(prog="dptpu bench camera_bursts", description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="640x480", help="image size WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--rate", type=float, default=200.0, help="viky's frame rate, 1..200 Hz (default 200)")
    parser.add_argument("--steps", type=int, default=12, help="steps of each of the scan's 2 frequencies (12)")
    parser.add_argument("--seconds", type=float, default=3.0, help="length of each window (default 3 s)")
    parser.add_argument("--rounds", type=int, default=4, help="idle and scans windows a run (default 4)")
    parser.add_argument("--pairs", type=int, default=3, help="alternating runs of each variant (default 3)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    if not 1 <= args.rate <= 200 or args.steps < 3 or args.seconds <= 0 or args.rounds < 1 or args.pairs < 1:
        print("dptpu bench camera_bursts: --rate must be 1..200, --steps >= 3, --seconds > 0, --rounds and --pairs "
              ">= 1", file=sys.stderr)
        return 2
    runs: dict[str, list[dict]] = {"frames": [], "bursts": []}
    for _ in range(args.pairs):
        for variant, values in runs.items():
            values.append(run_once(bursts=variant == "bursts", size=args.size, rate=args.rate, steps=args.steps,
                                   seconds=args.seconds, rounds_count=args.rounds))
    report = {"size": args.size, "rate": args.rate, "steps": args.steps, "seconds": args.seconds,
              "rounds": args.rounds, "runs": runs,
              "median_us_per_frame": {variant: round(float(np.median([r["us_per_frame"] for r in values])), 1)
                                      for variant, values in runs.items()},
              "median_handling_us_per_frame": {
                  variant: round(float(np.median([r["handling_us_per_frame"] for r in values])), 1)
                  for variant, values in runs.items()},
              "median_idle_cpu_s_per_s": {variant: round(float(np.median([r["idle_cpu_s_per_s"] for r in values])), 4)
                                          for variant, values in runs.items()}}
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        for variant, values in runs.items():
            print(f"{variant}: handling {report['median_handling_us_per_frame'][variant]:.1f} us of thread CPU a "
                  f"frame (runs {[r['handling_us_per_frame'] for r in values]}); process "
                  f"{report['median_us_per_frame'][variant]:.1f} us a frame above idle (runs "
                  f"{[r['us_per_frame'] for r in values]}), idle {report['median_idle_cpu_s_per_s'][variant]:.3f} "
                  "CPU s/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
