"""The scanner graph with the consumers a robot puts beside it, side by side with the plain graph (not a test).

``bench pipeline`` times the graph with one consumer, the scan monitor, which lets each cloud go at once. A robot's
consumers keep them: a SLAM front end or a map accumulator keeps the last clouds, a recorder queues them behind its
writes, the ROS 2 bridge converts each one. Each kept cloud holds its shared-memory segment (docs/graph.md,
"What a subscriber that keeps messages costs"), so the cloud node fills new segments until its pool is at its
bytes. This bench runs the sim rig (``launch/sim_rig.yaml``, as ``bench pipeline``'s throughput run: four scans in
flight, the monitor on clouds and statuses only) once per consumer set, in one invocation, and reports for each
the scans per second, the latency, each process's CPU a scan, the cloud node's duration and, at the end of the
timed window, the memory of the cloud node and of the consumers (resident, shared, segments held)::

    dptpu bench consumers [--json] [--size 640x480] [--source FOLDER|raycast] [--steps 3] [--scans 20]
                          [--warmup 10] [--consumers plain,keep1,keep10,keep100,record,ros2,viewer]
    dptpu bench consumers --fill [--size 640x480]
    dptpu bench consumers --paced 12 [--idle-s 10,60] [--rounds 2] [--scans 5] [--warmup 2]
    python benchmarks/consumers_bench.py [same options]

Consumer sets: ``plain`` (the monitor alone), ``keepN`` (a subscriber process that keeps the last N clouds in a
list, :func:`keep_clouds`), ``record`` (``dptpu record /scanner/points`` into an MCAP file), ``ros2`` (the launch's
ROS 2 bridge, ``ros2:=true``), ``viewer`` (the launch's web viewer, ``viewer:=true``, with nobody watching).
``--paced S`` runs the plain graph with a scan every S seconds (a robot that scans, moves, scans), once per
``DPTPU_SHM_IDLE_S`` value of ``--idle-s``: a pool closes the segments idle that long, and the next scan makes them
again. ``--fill`` launches nothing: it times the cloud node's fill into a reused and into a new segment
(:func:`fresh_segment_fill_ms`). Results: docs/benchmarks.md, "Consumers that keep clouds (issue 20, 20R)".
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

if __package__ in (None, ""):  # run as a script: benchmarks/ is not a package
    sys.path.insert(0, str(Path(__file__).resolve().parent))

import pipeline_bench

CONSUMERS = ("plain", "keep1", "keep10", "keep100", "record", "ros2", "viewer")


def keep_clouds(count: int) -> None:
    """A subscriber process that keeps the last ``count`` clouds of ``/scanner/points`` (a SLAM front end's
    window), until SIGTERM."""
    import collections
    import signal

    from dptpu import graph as rclpy
    from dptpu.graph.node import Node
    from dptpu.messages.sensor import PointCloud2

    rclpy.init(args=[])
    node = Node("cloud_keeper")
    kept: collections.deque = collections.deque(maxlen=count)
    node.create_subscription(PointCloud2, "/scanner/points", kept.append, 10)
    signal.signal(signal.SIGTERM, lambda *_: rclpy.try_shutdown())
    try:
        rclpy.spin(node)
    except Exception:  # noqa: BLE001 -- shut down by SIGTERM: the bench reads nothing from this process
        pass


def side_commands(consumer: str, folder: Path) -> tuple[dict[str, list[str]], list[str]]:
    """``(side processes, launch arguments)`` of one consumer set."""
    if consumer.startswith("keep"):
        return {f"keeper{consumer[4:]}": [sys.executable, __file__, "--keeper", consumer[4:]]}, []
    if consumer == "record":
        return {"recorder": [sys.executable, "-c", "import sys; from dptpu.cli.main import main; sys.exit(main())",
                             "record", "/scanner/points", "-o", str(folder / "points.mcap"),
                             "--compression", "none"]}, []
    if consumer == "ros2":
        return {}, ["ros2:=true", "ros_domain_id:=97"]
    if consumer == "viewer":
        return {}, ["viewer:=true", f"viewer_port:={18000 + os.getpid() % 1000}"]
    return {}, []


def run_consumer(consumer: str, args) -> dict:
    """One launch of the sim rig with ``consumer`` beside the monitor; its figures."""
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="dpc", dir="/tmp"))
    side, launch_args = side_commands(consumer, folder)
    sequence = pipeline_bench.SEQUENCES[args.steps]
    report = pipeline_bench.launch_sim_rig(
        sequence=sequence, model="none", size=args.size, scans=args.warmup + args.scans, timeout_s=args.timeout,
        pacing=["in_flight:=4", "monitor_triggers:=false", *launch_args],
        cpu_window=(args.warmup + 1, args.warmup + args.scans - 1), source=args.source, side_commands=side)
    figures = pipeline_bench.timed_figures(report, args.scans)
    recorded = folder / "points.mcap"
    cpu = report.get("cpu_ms_per_scan") or {}
    return {"consumers": consumer, "scans_per_s": figures["scans_per_s"],
            "latency_ms_p50": figures["latency_ms_p50"], "latency_ms_p99": figures["latency_ms_p99"],
            "scans_failed": figures["scans_failed"], "scans_lost": figures["scans_lost"],
            "cloud_ms_p50": next((v for k, v in figures["node_duration_ms_p50"].items() if "cloud" in k), None),
            "cpu_ms_per_scan": {k: v for k, v in cpu.items() if k != "threads"},
            "memory_mb": report.get("memory_mb"),
            "recorded_mb": round(recorded.stat().st_size / (1 << 20), 1) if recorded.is_file() else None}


def run_paced(period_s: float, idle_s: float, args) -> dict:
    """The plain graph with the projector starting a scan every ``period_s`` seconds (a robot that scans, moves,
    scans) and the pools closing segments idle for ``idle_s`` (``DPTPU_SHM_IDLE_S``); its figures."""
    previous = os.environ.get("DPTPU_SHM_IDLE_S")
    os.environ["DPTPU_SHM_IDLE_S"] = f"{idle_s:g}"  # the launch's processes inherit it
    try:
        report = pipeline_bench.launch_sim_rig(
            sequence=pipeline_bench.SEQUENCES[args.steps], model="none", size=args.size,
            scans=args.warmup + args.scans, timeout_s=args.timeout,
            pacing=["in_flight:=0", "projector_scans:=-1", f"scan_period:={period_s:.6f}"],  # the monitor times from
            # the Triggers (with monitor_triggers:=false it never hears of the projector's own scans)
            cpu_window=(args.warmup + 1, args.warmup + args.scans - 1), source=args.source)
    finally:
        if previous is None:
            os.environ.pop("DPTPU_SHM_IDLE_S", None)
        else:
            os.environ["DPTPU_SHM_IDLE_S"] = previous
    figures = pipeline_bench.timed_figures(report, args.scans)
    cpu = report.get("cpu_ms_per_scan") or {}
    return {"consumers": f"plain, a scan every {period_s:g} s, segments closed after {idle_s:g} s idle",
            "period_s": period_s, "idle_s": idle_s, "scans_per_s": figures["scans_per_s"],
            "latency_ms_p50": figures["latency_ms_p50"], "latency_ms_p99": figures["latency_ms_p99"],
            "scans_failed": figures["scans_failed"], "scans_lost": figures["scans_lost"],
            "cloud_ms_p50": next((v for k, v in figures["node_duration_ms_p50"].items() if "cloud" in k), None),
            "cpu_ms_per_scan": {k: v for k, v in cpu.items() if k != "threads"},
            "memory_mb": report.get("memory_mb"), "recorded_mb": None}


def fresh_segment_fill_ms(size: str = "640x480", repeats: int = 15) -> dict:
    """Median ms of the cloud node's fill (``cv2.merge`` of 9 float32 planes into a loaned segment) into a segment
    written before (``reused``: what a consumer that lets clouds go gives), into a new one as the pool makes it
    (``fresh``: every cloud while a consumer keeps them all, until the pool is at its bytes; ``make`` the making,
    ``fresh_total`` both) and into a new one without ``MAP_POPULATE`` (``fresh_faulted``: its pages faulted in by the
    fill), alternated in one process."""
    import time

    import cv2
    import numpy as np

    from dptpu.graph import segment_pool
    from dptpu.graph.shared_memory import SharedMemoryConfig

    width, height = (int(n) for n in size.split("x"))
    planes = [np.random.default_rng(i).random((height, width), dtype=np.float32) for i in range(9)]
    spec = (height, width, 9)
    nbytes = height * width * 9 * 4
    times: dict[str, list[float]] = {"reused": [], "make": [], "fresh": [], "fresh_faulted": []}
    populate = segment_pool._POPULATE
    pool = segment_pool.SegmentPool(SharedMemoryConfig(pool_bytes=1 << 40, key=b"bench"), "bench:fill")
    try:
        def fill(segment, entries) -> float:
            (offset, _), = entries
            cloud = segment.array[offset:offset + nbytes].view(np.float32).reshape(spec)
            start = time.perf_counter()
            cv2.merge(planes, dst=cloud)
            return time.perf_counter() - start

        warm = pool.loan([nbytes])
        fill(*warm)
        for _ in range(repeats):
            times["reused"].append(fill(*warm))
            for key, flags in (("fresh", populate), ("fresh_faulted", 0)):
                segment_pool._POPULATE = flags
                start = time.perf_counter()
                taken = pool.loan([nbytes])  # the others are all lent: a new segment
                made = time.perf_counter() - start
                times[key].append(fill(*taken))
                if key == "fresh":
                    times["make"].append(made)
                pool.cancel_loan(taken[0])
                pool._segments.remove(taken[0])  # closed at once: the next loan makes a new one again
                pool._bytes -= taken[0].size
                taken[0].close()
    finally:
        segment_pool._POPULATE = populate
        pool.close()
    figures = {key: round(1e3 * float(np.median(values)), 2) for key, values in times.items()}
    figures["fresh_total"] = round(figures["make"] + figures["fresh"], 2)
    figures["segment_mb"] = round(nbytes / (1 << 20), 1)
    return figures


def _line(r: dict) -> str:
    cpu = r["cpu_ms_per_scan"]
    graph = {k: v for k, v in cpu.items() if k not in ("total", "scans", "window_s")}
    memory = r["memory_mb"] or {}
    cloud = memory.get("cloud", {})
    return (f"{r['consumers']:<8} {r['scans_per_s']:6.2f} scans/s  latency p50 {r['latency_ms_p50']} p99 "
            f"{r['latency_ms_p99']} ms  cloud node {r['cloud_ms_p50']} ms  CPU total {cpu.get('total')} ms/scan "
            f"({', '.join(f'{k} {v}' for k, v in graph.items())})  cloud process RSS {cloud.get('rss')} MiB, "
            f"shmem {cloud.get('shmem')}, {cloud.get('segments')} segments {cloud.get('segment_mb')} MiB  "
            f"failed {r['scans_failed']} lost {r['scans_lost']}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="dptpu bench consumers", description=__doc__.split("\n")[0])
    parser.add_argument("--keeper", type=int, default=0, help=argparse.SUPPRESS)  # the side process itself
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--source", default="raycast")
    parser.add_argument("--steps", type=int, default=3, choices=sorted(pipeline_bench.SEQUENCES))
    parser.add_argument("--scans", type=int, default=20)
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--consumers", default=",".join(CONSUMERS))
    parser.add_argument("--paced", type=float, default=0.0,
                        help="the plain graph with a scan every PACED s, once per --idle-s value (alternated)")
    parser.add_argument("--idle-s", default="10,60", help="with --paced: DPTPU_SHM_IDLE_S values (default 10,60)")
    parser.add_argument("--rounds", type=int, default=1, help="with --paced: runs of each value (default 1)")
    parser.add_argument("--fill", action="store_true",
                        help="no graph: the cloud node's fill into a reused, a fresh and a fresh unpopulated segment")
    args = parser.parse_args(argv)
    if args.keeper:
        keep_clouds(args.keeper)
        return 0
    if args.fill:
        print(json.dumps(fresh_segment_fill_ms(args.size)))
        return 0
    try:
        idle_values = [float(v) for v in args.idle_s.split(",") if v.strip()]
    except ValueError:
        idle_values = []
    if not idle_values or min(idle_values) <= 0 or args.rounds < 1:
        print(f"dptpu bench consumers: error: --idle-s takes seconds > 0 (e.g. 10,60), --rounds >= 1; got "
              f"{args.idle_s!r}, {args.rounds}", file=sys.stderr)
        return 2
    if args.paced > 0:
        results = []
        for _ in range(args.rounds):
            for idle_s in idle_values:
                results.append(run_paced(args.paced, idle_s, args))
                if not args.json:
                    print(_line(results[-1]), flush=True)
        if args.json:
            print(json.dumps({"benchmark": "consumers-paced", "load_average": list(os.getloadavg()),
                              "results": results}, indent=1))
        return 0
    consumers = [c for c in args.consumers.split(",") if c]
    unknown = [c for c in consumers if c not in CONSUMERS and not (c.startswith("keep") and c[4:].isdigit())]
    if unknown or not 2 <= args.scans <= 200:
        print(f"dptpu bench consumers: error: --consumers takes {', '.join(CONSUMERS)} (keepN for any N), --scans "
              f"2..200; got {', '.join(unknown) or args.consumers}, {args.scans}", file=sys.stderr)
        return 2
    results = []
    for consumer in consumers:
        results.append(run_consumer(consumer, args))
        if not args.json:
            print(_line(results[-1]), flush=True)
    if args.json:
        print(json.dumps({"benchmark": "consumers", "machine": {"cpus": os.cpu_count(),
                                                               "platform": platform.platform(),
                                                               "load_average": list(os.getloadavg())},
                          "size": args.size, "steps": args.steps, "source": args.source, "results": results},
                         indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
