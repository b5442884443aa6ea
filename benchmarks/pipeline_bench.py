"""``dptpu bench pipeline``: the whole scanner graph end to end, scans per second and latency (not a test).

Each configuration runs ``launch/sim_rig.yaml`` as real processes (projector on the emulated trigger box, sim,
phase, unwrap, cloud, scan monitor) with the sim as fast as possible (no frame-rate limit, 100 us per pattern on
the emulated box) and ground truth off (the monitor only times), twice:

1. **Throughput** (``--in-flight`` scans, default 4): the monitor keeps that many scans started ahead of the last
   one it reported (scan on demand: a scan starts only when an earlier one is reported, so the graph is never
   overrun and no scan is dropped). Two in flight leave the graph idle between a report and the next start (the
   service call, the projection, the first frames) and cap the rate near ``2 / latency`` by construction; four
   keep every stage busy, so the graph, not the bench, is the bottleneck. The monitor takes what a robot takes,
   the clouds (and the scan statuses), not every pattern's Trigger (``monitor_triggers:=false``). The phase
   node's frame queue (100 frames) holds four 24-frame scans: more in flight would drop frames, so the bench
   stays at four. The sim hands the phase node each entry's frames as one FringeBurst (``--frames single``: a
   FringeFrame a pattern, as before issue 20's bursts), and the projector hands the sim each entry's Triggers as
   one TriggerBurst (``--triggers single``: a Trigger a pattern).
   ``scans_per_s = (n - 1) / (t_n - t_1)`` over the arrival times of the ``--scans`` timed clouds at the monitor
   (after ``--warmup`` scans).
2. **Latency** at a pace the graph sustains: the projector starts its own scans every ``1 / (f * scans_per_s)``
   seconds (``f = --latency-load``, default 0.5; ``scans_per_s`` capped at the camera limit below, since a
   rate taken from a few scans can be wild), as a camera-paced rig that projects continuously does, and the
   monitor starts none. 0.5 leaves room for the other jobs of a shared machine: at 0.8 under a load average of
   11 on 2 cores the graph fell behind now and then, frames overflowed the phase node's queue and scans failed
   as incomplete (which is what a camera-paced rig does when overrun, and what the run reports).
   ``latency_ms_p50`` / ``latency_ms_p99`` over the timed scans: from the scan's last Trigger (the stamp its
   frames and cloud carry) to its cloud's arrival at the monitor. (The throughput run's
   latencies, which include the queueing of four scans in flight, are ``throughput.latency_ms_p50`` / ``p99``.)
   ``--latency-load 0`` skips this run and reports the throughput run's latencies.

Every timed scan must be complete: the phase node never mixes two scans and drops an incomplete one with a
ScanStatus, the monitor reports a scan ``failed`` or ``lost`` otherwise; ``scans_failed`` and ``scans_lost``
count those among the timed scans (``warmup_failed`` the others), and ``valid_points_min`` is the smallest cloud.

Further figures: ``cpu_ms_per_scan`` (each process's CPU time, every thread, from ``/proc/<pid>/stat`` over the
throughput run's timed scans, divided by their number; ``total`` sums them: on C cores the graph can do at most
``1000 * C / total`` scans/s; ``threads``: each process split into its main thread, libzmq's I/O thread and the
others), ``node_duration_ms_p50`` (each node's median ``ScanStatus.duration_s``, from the throughput
run), ``camera_limit_ratio``: ``scans_per_s`` over what the paper's camera allows, the Basler acA640-750 at 750
frames/s: 31.25 scans/s at 24 frames (2 x 12 steps), 125 at 6 frames (2 x 3 steps).

Configurations: 2 x 12-step (``64x12,1x12``) and 2 x 3-step (``64x3,1x3``), MF, classical and, when a DP-TPU
model is available (``dptpu.models.inference.shipped_model_path()`` or ``--model``), DP-TPU. Run::

    dptpu bench pipeline [--json] [--size 640x480] [--scans 60] [--warmup 10] [--in-flight 4]
                         [--latency-load 0.5] [--steps 12,3] [--model FILE.onnx] [--classical-only | --dptpu-only]
    dptpu bench pipeline --floor [--json] [--size 640x480] [--steps 12,3] [--source raycast|FOLDER|ramp]
    python benchmarks/pipeline_bench.py [same options]

``--floor`` launches nothing: it times, in one process, the work of a scan that no graph can take away (frames in
and the cloud out through ZeroMQ, the phase, the unwrapping, the triangulation; :func:`floor_ms_per_scan`), the
lower bound of ``cpu_ms_per_scan["total"]``, on the first scene the graph scans with the same ``--source``.

Results and the machine they were taken on: docs/benchmarks.md, "bench pipeline".
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
SIM_RIG = REPO_ROOT / "launch" / "sim_rig.yaml"
#: The twin's rig ``launch/sim_rig.yaml`` renders with by default.
SHIPPED_RIG = REPO_ROOT / "launch" / "params" / "shipped_rig.yaml"
#: ``--floor --source`` of the floor's analytic ramp across the projector (a steep plane; no graph replays it).
ANALYTIC_RAMP = "ramp"
#: The paper's camera, Basler acA640-750um: frames per second at 640x480.
CAMERA_FRAMES_PER_S = 750.0
SEQUENCES = {12: "64x12,1x12", 3: "64x3,1x3"}
DOMAIN_ID = 97
#: Frames the phase node's subscription queues (``frame_queue_depth``): scans in flight x frames must fit.
PHASE_FRAME_QUEUE = 100
#: Untimed scans of the floor before its timed ones: the heap grows to what a scan needs (with two, the step count
#: measured first in a process ran 20-30 % slower than the same work measured second: docs/benchmarks.md, "Floor
#: kernels, session 10").
FLOOR_WARMUPS = 10
#: The raycast scenes the sim shows, in scan order.
SCENES = "random:1,random:2"


def camera_limit_scans_per_s(frames_per_scan: int) -> float:
    """Scans per second the acA640-750 allows: 750 / frames (31.25 at 24 frames, 125 at 6)."""
    return CAMERA_FRAMES_PER_S / frames_per_scan


def launch_sim_rig(*, sequence: str, model: str, size: str, scans: int, timeout_s: float,
                   pacing: list[str], cpu_window: tuple[int, int] | None = None, source: str = "raycast",
                   side_commands: dict[str, list[str]] | None = None, frame_bursts: bool = True,
                   trigger_bursts: bool = True) -> dict:
    """Run the sim rig until ``scans`` scans were reported; the monitor's summary (``totals``, ``scans``).

    ``pacing`` holds the launch arguments that start the scans (``in_flight:=N``, or ``in_flight:=0
    projector_scans:=-1 scan_period:=S``). With ``cpu_window = (a, b)`` the summary also holds
    ``cpu_ms_per_scan``: each process's CPU time (user + system, every thread, ``/proc/<pid>/stat``) from the
    monitor's ``a``-th reported scan to its ``b``-th, divided by ``b - a`` (:func:`cpu_per_scan_ms`). ``source``:
    the sim node's (``raycast`` renders :data:`SCENES` live; a folder of ``dptpu-capture/1`` captures is replayed).
    ``side_commands``: ``{name: argv}`` of further processes of the same graph (consumers beside the monitor, e.g.
    ``benchmarks/consumers_bench.py``'s), started with the launch and stopped (SIGTERM) at its end; their CPU is
    measured as the launch's processes'. With a ``cpu_window`` the summary also holds ``memory_mb``: each process's
    memory in the middle of the window (:func:`process_memory_mb`; at its end the launch may be closing them).
    """
    folder = Path(tempfile.mkdtemp(prefix="dpb", dir="/tmp"))
    summary = folder / "summary.json"
    env = dict(os.environ, DPTPU_DISCOVERY_DIR=str(folder / "d"), DPTPU_DOMAIN_ID=str(DOMAIN_ID),
               PYTHONPATH=str(REPO_ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    command = [sys.executable, "-c", "import sys; from dptpu.cli.main import main; sys.exit(main())", "launch",
               str(SIM_RIG), f"scans:={scans}", f"size:={size}", f"sequence:={sequence}", "method:=mf",
               f"model:={model}", "ground_truth:=false", "exposure_us:=100", "ply_dir:=", f"summary:={summary}",
               f"scenes:={SCENES}", f"source:={source}", f"frame_bursts:={str(frame_bursts).lower()}",
               f"trigger_bursts:={str(trigger_bursts).lower()}", *pacing]
    process = subprocess.Popen(command, cwd=folder, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    killer = threading.Timer(timeout_s, process.kill)
    killer.start()
    pids = {"launch": process.pid}
    side = {name: subprocess.Popen(argv, cwd=folder, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL) for name, argv in (side_commands or {}).items()}
    pids.update({name: side_process.pid for name, side_process in side.items()})
    reported, samples, tail, memory = 0, [], [], {}
    try:
        for line in process.stdout:  # the launch's prefixed lines, as they come
            tail = (tail + [line])[-40:]
            started = _STARTED.search(line)
            if started:
                pids[started.group(1)] = int(started.group(2))
            elif _REPORTED.match(line):
                reported += 1
                if cpu_window is not None and reported in cpu_window:
                    samples.append((reported, time.monotonic(), cpu_times_s(pids)))
                if cpu_window is not None and reported == sum(cpu_window) // 2:  # mid-window: none is ending yet
                    memory = {name: process_memory_mb(pid) for name, pid in pids.items()}
        returncode = process.wait()
    finally:
        for side_process in side.values():
            side_process.terminate()
            try:
                side_process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                side_process.kill()
                side_process.wait()
        killer.cancel()
        if process.poll() is None:
            process.kill()
            process.wait()
    try:
        if returncode != 0 or not summary.is_file():
            raise RuntimeError(f"the sim rig exited with {returncode}: {''.join(tail)[-2000:]}")
        report = json.loads(summary.read_text())
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    if len(samples) == 2:
        report["cpu_ms_per_scan"] = cpu_per_scan_ms(samples[0], samples[1])
        report["memory_mb"] = memory
    return report


def process_memory_mb(pid: int) -> dict:
    """``{"rss": MiB, "shmem": MiB, "segments": n, "segment_mb": MiB}`` of a process now: its resident memory and,
    of it, the shared memory it maps (``/proc/<pid>/status`` VmRSS, RssShmem), and the graph's shared-memory
    segments it holds open (``memfd:dptpu...`` files: its publishers' pools and the segments it maps) and their size,
    in all and by topic (``by_topic``: ``{label: [segments, MiB]}``, the label ``dptpu:scanner:points`` for
    ``/scanner/points``); ``{}`` when it is gone."""
    try:
        status = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
        descriptors = list(Path(f"/proc/{pid}/fd").iterdir())
    except (OSError, ValueError):
        return {}
    sizes = {}  # inode -> (label, bytes) (a segment is open twice: its memfd and the duplicate Python's mmap keeps)
    for fd in descriptors:
        try:
            target = os.readlink(fd)
            if target.startswith("/memfd:dptpu"):
                sizes[fd.stat().st_ino] = (target[7:].removesuffix(" (deleted)"), fd.stat().st_size)
        except OSError:  # closed since listed
            continue
    topics: dict[str, list] = {}  # label (the publisher's topic, / as :) -> [segments, MiB]
    for label, nbytes in sizes.values():
        entry = topics.setdefault(label, [0, 0.0])
        entry[0] += 1
        entry[1] = round(entry[1] + nbytes / (1 << 20), 1)
    kib = {key: int(status.get(key, "0 kB").split()[0]) for key in ("VmRSS", "RssShmem")}
    return {"rss": round(kib["VmRSS"] / 1024, 1), "shmem": round(kib["RssShmem"] / 1024, 1), "segments": len(sizes),
            "segment_mb": round(sum(nbytes for _, nbytes in sizes.values()) / (1 << 20), 1), "by_topic": topics}


_STARTED = re.compile(r"^\[launch\] started '([\w.-]+)' \(pid (\d+)\)")
_REPORTED = re.compile(r"^\[scan_monitor\] scan \d+\b[^:]*: (ok|FAILED|LOST)\b")


#: Thread kinds of ``cpu_ms_per_scan_threads``: libzmq's I/O thread moves the bytes between the sockets (the kernel's
#: copies); every other thread but the main one is Python's (the graph runtime's I/O thread, pyzmq's garbage
#: collector of zero-copy frames, the projector's serial link).
_THREAD_KINDS = {"ZMQbg/IO/0": "zmq_io"}


def _stat_cpu_s(stat_path: Path, ticks_per_s: int) -> float:
    fields = stat_path.read_text().rpartition(")")[2].split()
    return (int(fields[11]) + int(fields[12])) / ticks_per_s  # utime, stime (fields 14, 15)


def cpu_times_s(pids: dict[str, int]) -> dict[str, tuple[int, float, dict]]:
    """``{name: (pid, user + system CPU seconds, {thread id: (kind, seconds)})}`` of the processes still alive
    (``/proc/<pid>/stat`` and ``/proc/<pid>/task/*/stat``; Linux). Thread kinds: ``main``, ``zmq_io`` (libzmq's
    I/O thread), ``other`` (the rest)."""
    ticks_per_s = os.sysconf("SC_CLK_TCK")
    times = {}
    for name, pid in pids.items():
        try:
            total = _stat_cpu_s(Path(f"/proc/{pid}/stat"), ticks_per_s)
        except OSError:
            continue
        threads = {}
        try:
            tasks = list(Path(f"/proc/{pid}/task").iterdir())
        except OSError:  # the process ended after its total was read
            tasks = []
        for task in tasks:
            try:
                kind = "main" if task.name == str(pid) else _THREAD_KINDS.get(
                    (task / "comm").read_text().strip(), "other")
                threads[task.name] = (kind, _stat_cpu_s(task / "stat", ticks_per_s))
            except OSError:  # the thread ended while listed
                continue
        times[name] = (pid, total, threads)
    return times


def _thread_kinds_ms(first: dict, last: dict, scans: int) -> dict[str, float]:
    """CPU ms per scan by thread kind between two samples of one process's threads: each thread alive at the
    last sample from its first sample (0 if it started inside the window); a thread that ended inside the window
    is missing, so no kind goes below 0."""
    kinds = {"main": 0.0, "zmq_io": 0.0, "other": 0.0}
    for tid, (kind, seconds) in last.items():
        before = first.get(tid)
        kinds[kind] += seconds - (before[1] if before is not None and before[0] == kind else 0.0)
    return {kind: round(1e3 * value / scans, 2) for kind, value in kinds.items()}


def cpu_per_scan_ms(first: tuple, last: tuple) -> dict:
    """Each process's CPU ms per scan between two samples ``(reported scans, monotonic s, cpu_times_s())``; a
    process respawned in between (another pid) is left out. ``total`` sums them; ``scans`` and ``window_s``
    describe the window; ``threads`` splits each process by thread kind (:func:`cpu_times_s`; a thread that
    ended inside the window is missing there)."""
    (count0, time0, cpu0), (count1, time1, cpu1) = first, last
    scans = count1 - count0
    kept = [name for name in cpu1 if name in cpu0 and cpu0[name][0] == cpu1[name][0]]
    figures = {name: round(1e3 * (cpu1[name][1] - cpu0[name][1]) / scans, 1) for name in kept}
    figures["total"] = round(sum(figures.values()), 1)
    figures.update(scans=scans, window_s=round(time1 - time0, 2))
    figures["threads"] = {name: _thread_kinds_ms(cpu0[name][2], cpu1[name][2], scans) for name in kept}
    return figures


def timed_figures(report: dict, scans: int) -> dict:
    """Rate, latency and outcomes of the last ``scans`` reported scans of a monitor summary."""
    records = sorted(report["scans"], key=lambda r: r["sequence_id"])  # a lost scan is reported seconds late
    timed = records[-scans:]  # the last scans started (the monitor keeps the last 200 records)
    ok = [r for r in timed if r["outcome"] == "ok"]
    arrivals = np.array([r["cloud_arrival_unix_s"] for r in ok])
    latency = np.array([r["latency_ms"] for r in ok])
    rate = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0]) if len(arrivals) > 1 else float("nan")
    first = np.array([r.get("latency_from_first_trigger_ms", np.nan) for r in ok])
    totals = report["totals"]
    return {
        "scans_timed": len(ok), "scans_per_s": round(float(rate), 3),
        "latency_ms_p50": round(float(np.percentile(latency, 50)), 1) if ok else None,
        "latency_ms_p99": round(float(np.percentile(latency, 99)), 1) if ok else None,
        "latency_from_first_trigger_ms_p50": round(float(np.nanpercentile(first, 50)), 1)
        if np.isfinite(first).any() else None,
        "scans_failed": sum(r["outcome"] == "failed" for r in timed),
        "scans_lost": sum(r["outcome"] == "lost" for r in timed),
        "failure_reasons": [f"scan {r['sequence_id']}: {r.get('reason', '')}" for r in timed if r["outcome"] != "ok"],
        "warmup_failed": int(totals["failed"] + totals["lost"]) - sum(r["outcome"] != "ok" for r in timed),
        "valid_points_min": int(min(r["valid_points"] for r in ok)) if ok else 0,
        "node_duration_ms_p50": _node_durations_ms(ok),
    }


def run_configuration(*, steps: int, model: str, size: str, scans: int, warmup: int, in_flight: int,
                      latency_load: float, timeout_s: float, source: str = "raycast",
                      frame_bursts: bool = True, trigger_bursts: bool = True) -> dict:
    """Launch the sim rig for one configuration (throughput run, then latency run); the module docstring's
    figures."""
    sequence = SEQUENCES[steps]
    frames = sum(int(entry.split("x")[1]) for entry in sequence.split(","))
    started = time.monotonic()
    common = {"sequence": sequence, "model": model, "size": size, "scans": warmup + scans, "timeout_s": timeout_s,
              "source": source, "frame_bursts": frame_bursts, "trigger_bursts": trigger_bursts}
    # the monitor as a robot: clouds and statuses only (the latency run takes the Triggers for the first pattern)
    throughput_report = launch_sim_rig(pacing=[f"in_flight:={in_flight}", "monitor_triggers:=false"],
                                       cpu_window=(warmup + 1, warmup + scans - 1), **common)
    throughput = timed_figures(throughput_report, scans)
    rate = throughput["scans_per_s"]
    latency = throughput
    if latency_load > 0 and np.isfinite(rate) and rate > 0:
        # paced at a share of the measured rate, never above the camera's own limit: a rate taken from a few
        # scans can be wild (two clouds arriving together), and no projector starts scans faster than that
        period_s = 1.0 / (latency_load * min(rate, camera_limit_scans_per_s(frames)))
        latency = timed_figures(launch_sim_rig(pacing=["in_flight:=0", "projector_scans:=-1",
                                                       f"scan_period:={period_s:.6f}"], **common), scans)
        latency["scan_period_s"] = round(period_s, 5)
    return {
        "configuration": f"2 x {steps}-step, {'DP-TPU' if model != 'none' else 'classical'} MF",
        "sequence": sequence, "frames_per_scan": frames, "method": "mf", "model": model, "size": size, "source": source,
        "frame_bursts": frame_bursts, "trigger_bursts": trigger_bursts,
        "in_flight": in_flight, "latency_load": latency_load if latency is not throughput else None,
        "scans_timed": min(throughput["scans_timed"], latency["scans_timed"]),
        "scans_failed": throughput["scans_failed"] + (latency["scans_failed"] if latency is not throughput else 0),
        "scans_lost": throughput["scans_lost"] + (latency["scans_lost"] if latency is not throughput else 0),
        "failure_reasons": throughput["failure_reasons"] + (latency["failure_reasons"] if latency is not throughput
                                                            else []),
        "scans_per_s": rate,
        "latency_ms_p50": latency["latency_ms_p50"],
        "latency_ms_p99": latency["latency_ms_p99"],
        "latency_from_first_trigger_ms_p50": latency["latency_from_first_trigger_ms_p50"],
        "node_duration_ms_p50": throughput["node_duration_ms_p50"],
        "cpu_ms_per_scan": throughput_report.get("cpu_ms_per_scan"),
        "camera_limit_scans_per_s": camera_limit_scans_per_s(frames),
        "camera_limit_ratio": round(float(rate / camera_limit_scans_per_s(frames)), 4),
        "throughput": throughput,
        "latency": latency if latency is not throughput else None,
        "wall_s": round(time.monotonic() - started, 1),
    }


def _node_durations_ms(records) -> dict:
    """Median ``ScanStatus.duration_s`` of each node over ``records``, ms (docs/nodes.md: phase from the scan's first
    frame's arrival, unwrap its own unwrapping, cloud from the scan's last frame to the cloud)."""
    nodes = sorted({node for r in records for node in r.get("node_durations_s", {})})
    return {node: round(1e3 * float(np.median([r["node_durations_s"][node] for r in records
                                                if node in r.get("node_durations_s", {})])), 1) for node in nodes}


def floor_ms_per_scan(*, steps: int, size: str, repeats: int = 30, source: str = "raycast") -> dict:
    """The work of one scan that no graph can take away, in one process with the repo's fastest kernels (CPU ms).

    What a scanner must do however it is built: take the scan's frames in through ZeroMQ (``transport_in``: the
    camera's send and the scanner's receive of ``2 * steps`` mono8 frames, ipc PUSH/PULL, both sides' CPU), the
    Eq. (2) sums and float32 arctangents of both entries with the modulation/saturation mask (``phase``,
    :func:`dptpu.fpp.phase.sequence_sums`, :func:`~dptpu.fpp.phase.maps_from_sums`, and the phase node's noise
    test of :mod:`dptpu.fpp.fringe_noise` on entries of 5 or more steps), Eq. (5) (``unwrap``,
    :func:`dptpu.fpp.tpu.unwrap_mf_float32`), the triangulation with both lens distortions into float32 metres
    (``triangulate``, :meth:`~dptpu.fpp.triangulate.Triangulator.camera_points` of the sim rig's rig at ``size``),
    the cloud node's default filters (``filters``: :func:`dptpu.fpp.depth_edges.edge_points` with the partly
    shadowed points' predicted error of :func:`~dptpu.fpp.shadow_border.depth_per_pixel`, a second triangulation of
    those pixels, and :func:`dptpu.fpp.order_islands.order_islands`),
    the (H, W, 9) cloud as the cloud node builds it (x, y, z planes, texture, modulation, confidence and the normals'
    planes of :func:`dptpu.fpp.organized_normals.organized_normals`, one ``cv2.merge``) with its depth and confidence
    images (``assemble``), all
    three sent to one subscriber (``transport_out``, both sides). No Python between processes, no messages but the
    frames and the outputs: a lower bound of the graph's CPU per scan (``total``). ``total_shared_memory`` moves the
    bytes as the shared-memory path does at the least, one copy each way (``copy_in``, ``copy_out``: ``np.copyto``
    into a preallocated array) instead of through ZeroMQ: the floor of a graph whose large messages go through
    shared memory. The frames are those of the first scene the graph scans with the same ``source``
    (``--source``): ``raycast``, random-1 rendered by the raycast twin as the sim node renders it (the launch
    file's rig, ``2 x steps`` frames, noise seed 0); a folder of ``dptpu-capture/1`` captures, its first capture's
    frames and rig. ``"ramp"`` (:data:`ANALYTIC_RAMP`, the floor only): an analytic ramp across the projector (64
    and 1 periods), a plane steeper than the flying-point test's slope (the default until 2026-11-27: the floor
    then measured kernels on a scene the graph never scans; docs/benchmarks.md, Run 15). Median of ``repeats``
    timings of each part (``time.process_time``, every thread) after :data:`FLOOR_WARMUPS` untimed scans.
    """
    import cv2
    import zmq

    from dptpu.fpp import phase as fpp_phase
    from dptpu.fpp import tpu
    from dptpu.fpp.depth_edges import DEFAULT_MAX_EDGE_ERROR_MM, edge_points
    from dptpu.fpp.fringe_noise import DEFAULT_MAX_NOISE_RATIO, noise_outliers, sequence_phase_noise
    from dptpu.fpp.order_islands import order_islands
    from dptpu.fpp.organized_normals import organized_normals
    from dptpu.fpp.shadow_border import depth_per_pixel
    from dptpu.fpp.triangulate import Triangulator, projector_coordinate
    from dptpu.sim.rig import load_twin_rig

    width, height = (int(v) for v in size.lower().split("x"))
    if source == ANALYTIC_RAMP:
        rig = load_twin_rig(SHIPPED_RIG, size=(width, height))
        extent = rig.projector.size[0]
        rows, cols = np.mgrid[0:height, 0:width]
        x_p = 40.0 + (extent - 80.0) * cols / width + 0.05 * rows  # (H, W) projector columns
        stacks = []
        for frequency in (64.0, 1.0):
            n = np.arange(steps)[:, None, None]
            phase = 2 * np.pi * frequency * x_p / extent
            stacks.append(np.round(128 + 100 * np.cos(phase - 2 * np.pi * n / steps)).astype(np.uint8))  # (N, H, W)
    else:
        from dptpu.nodes.sim.source import load_source

        # the graph's first scene as its sim node makes it: rendered live by the raycast twin (the launch file's
        # rig, the bench's scenes and sequence, noise seed 0) or replayed from the capture folder
        loaded = load_source(source, rig=str(SHIPPED_RIG), size=size, scenes=SCENES.split(",")[0],
                             sequence=SEQUENCES[steps])
        scenes, rig = loaded.scenes, loaded.rig
        stacks = [scenes[0].stack(frequency, steps) for frequency in (64.0, 1.0)]  # 3-step captures: frames 0, 4, 8
        if any(stack is None for stack in stacks) or stacks[0].shape[1:] != (height, width):
            raise RuntimeError(f"the first scene of {source} holds no 64x{steps} and 1x{steps} sequences at {size}")
        stacks = [np.ascontiguousarray(stack) for stack in stacks]  # as the phase node stacks its frames
        extent = rig.projector.size[0]
    triangulator = Triangulator(rig, axis="x")
    focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])

    context = zmq.Context()
    sender, receiver = context.socket(zmq.PUSH), context.socket(zmq.PULL)
    address = f"ipc:///tmp/dptpu-floor-{os.getpid()}"
    receiver.bind(address)
    sender.connect(address)

    def transfer(arrays):
        for array in arrays:
            sender.send(array, copy=False)
        for _ in arrays:
            receiver.recv(copy=False)

    copies: dict = {}

    def copy_once(arrays):  # what the shared-memory path costs at least: the writer's one copy into a segment
        for index, array in enumerate(arrays):
            target = copies.get((index, array.shape, array.dtype))
            if target is None:
                target = copies[(index, array.shape, array.dtype)] = np.empty_like(array)
            np.copyto(target, array)

    frames = [frame for stack in stacks for frame in stack]
    state = {}

    def phase_step():  # as the phase node does: with the phase-noise test of entries of 5 or more steps
        sums = [fpp_phase.sequence_sums(stack) for stack in stacks]
        maps = [fpp_phase.maps_from_sums(s) for s in sums]
        valid = np.ones((height, width), dtype=bool)
        for m in maps:
            valid &= m.modulation >= 10.0
        valid &= np.maximum.reduce([stack.max(axis=0) for stack in stacks]) < 255
        noise, floors = zip(*(sequence_phase_noise(stack, m.background, m.modulation)  # noise None below 5 steps
                              for stack, m in zip(stacks, maps)))
        valid &= ~noise_outliers(noise, valid, DEFAULT_MAX_NOISE_RATIO, floors)
        state["maps"], state["valid"] = maps, valid

    def unwrap_step():
        maps = state["maps"]
        state["unwrapped"] = tpu.unwrap_mf_float32(maps[0].phase, maps[1].phase, 64.0, 1.0, valid=state["valid"])

    def triangulate_step():  # as the cloud node does: into x, y, z planes (3, H, W)
        result = state["unwrapped"]
        coord = state["coord"] = projector_coordinate(result.absolute_phase, 64.0, extent)
        planes = state["planes"] = np.empty((3, *coord.shape), dtype=np.float32)
        triangulator.camera_points(coord, scale=rig.scale_to_m, dtype=np.float32, out=planes.transpose(1, 2, 0))

    def depth_at(projector_x, pixels):
        return triangulator.camera_points(projector_x, scale=rig.scale_to_m, dtype=np.float32, pixels=pixels)[:, 2]

    def filter_step():  # as the cloud node does by default: the points at depth edges (with the partly shadowed
        # ones judged by their predicted depth error: one more triangulation of those pixels), the islands of wrong
        # orders
        planes, result, modulation = state["planes"], state["unwrapped"], state["maps"][0].modulation
        depth = planes[2]

        def per_px(where):
            return depth_per_pixel(state["coord"], depth_at, "x", depth=depth, where=where)

        dropped = edge_points(depth, focal_px, modulation, lit=result.valid, depth_per_px=per_px,
                              max_edge_error=DEFAULT_MAX_EDGE_ERROR_MM * 1e-3, axis="x").dropped
        dropped |= order_islands(result.absolute_phase, modulation, result.valid).islands
        for plane in planes:  # blanked as the cloud node blanks them: a masked copy a plane
            np.copyto(plane, np.float32(np.nan), where=dropped)

    def assemble_step():  # as the cloud node does: texture, modulation, confidence and the normals' planes beside
        # the x, y, z planes, interleaved by one cv2.merge
        planes = state["planes"]
        confidence = np.where(np.isfinite(planes[2]), state["unwrapped"].reliability,
                              np.float32(0.0)).astype(np.float32, copy=False)
        normals = np.empty_like(planes)  # (3, H, W)
        organized_normals(planes.transpose(1, 2, 0), out=normals.transpose(1, 2, 0))
        state["cloud"] = cv2.merge([*planes, state["maps"][0].background, state["maps"][0].modulation, confidence,
                                    *normals])  # (H, W, 9)
        state["depth"], state["confidence"] = planes[2], confidence

    parts = {"transport_in": lambda: transfer(frames), "phase": phase_step, "unwrap": unwrap_step,
             "triangulate": triangulate_step, "filters": filter_step, "assemble": assemble_step,
             "transport_out": lambda: transfer([state["cloud"], state["depth"], state["confidence"]]),
             "copy_in": lambda: copy_once(frames),
             "copy_out": lambda: copy_once([state["cloud"], state["depth"], state["confidence"]])}
    times = {name: [] for name in parts}
    try:
        for _ in range(repeats + FLOOR_WARMUPS):
            for name, part in parts.items():
                started = time.process_time()
                part()
                times[name].append(time.process_time() - started)
    finally:
        sender.close(linger=0)
        receiver.close(linger=0)
        context.term()
    figures = {name: round(1e3 * float(np.median(values[FLOOR_WARMUPS:])), 2) for name, values in times.items()}
    work = sum(figures[name] for name in ("phase", "unwrap", "triangulate", "filters", "assemble"))
    figures["total"] = round(work + figures["transport_in"] + figures["transport_out"], 2)
    figures["total_shared_memory"] = round(work + figures["copy_in"] + figures["copy_out"], 2)
    figures["cores_2_scans_per_s_max"] = round(2000.0 / figures["total"], 1)
    figures.update(steps=steps, frames=2 * steps, size=size, source=source, valid_pixels=int(np.count_nonzero(
        np.isfinite(state["depth"]))))
    return figures


def measure_floor(step: int, size: str, source: str = "raycast") -> dict:
    """:func:`floor_ms_per_scan` with the allocator as every node sets it."""
    from dptpu.nodes.node_main import keep_freed_memory

    keep_freed_memory()  # as every node does
    return floor_ms_per_scan(steps=step, size=size, source=source)


#: The graph's CPU a scan over the floor: issue 20's goal.
FLOOR_RATIO_GOAL = 1.3


def attach_floor(result: dict, floor: dict) -> None:
    """Add the floor measured beside ``result`` and the graph's CPU a scan over it (``cpu_over_floor``: over the
    shared-memory floor, ``cpu_over_zeromq_floor``: over the floor with ZeroMQ transfers)."""
    cpu = (result.get("cpu_ms_per_scan") or {}).get("total")
    result["floor_ms_per_scan"] = floor
    result["cpu_over_floor"] = round(cpu / floor["total_shared_memory"], 3) if cpu else None
    result["cpu_over_zeromq_floor"] = round(cpu / floor["total"], 3) if cpu else None
    result["cpu_over_floor_goal"] = FLOOR_RATIO_GOAL


def _floor_line(f: dict) -> str:
    return (f"2 x {f['steps']}-step floor: {f['total_shared_memory']:.1f} ms CPU a scan with shared memory, "
            f"{f['total']:.1f} with ZeroMQ (at most {f['cores_2_scans_per_s_max']} scans/s on 2 cores): "
            + ", ".join(f"{k} {f[k]:.2f}" for k in ("transport_in", "copy_in", "phase", "unwrap", "triangulate",
                                                     "filters", "assemble", "transport_out", "copy_out")))


def dptpu_model(explicit: str | None) -> str | None:
    """The DP-TPU model to time: ``--model``, else the shipped one, else None."""
    if explicit:
        return explicit
    try:
        from dptpu.models.inference import shipped_model_path
    except ImportError:
        return None
    path = shipped_model_path()
    return str(path) if path is not None else None


def run(args) -> int:
    """Run the configurations of ``args`` (see :func:`build_parser`); print the report; 0, or 2 for bad options."""
    steps = [int(s) for s in str(args.steps).split(",") if s.strip().isdigit()]
    if not steps or any(s not in SEQUENCES for s in steps):
        print(f"dptpu bench pipeline: error: --steps takes 12 and/or 3; got {args.steps}", file=sys.stderr)
        return 2
    most_frames = max(2 * s for s in steps)
    if not 2 <= args.scans <= 200 or args.warmup < 0 or not 1 <= args.in_flight <= PHASE_FRAME_QUEUE // most_frames \
            or not 0 <= args.latency_load < 1:
        print("dptpu bench pipeline: error: --scans must be 2..200 (the monitor keeps 200 records), --warmup >= 0, "
              f"--in-flight 1..{PHASE_FRAME_QUEUE // most_frames} (the phase node queues {PHASE_FRAME_QUEUE} frames, "
              f"{most_frames} a scan), --latency-load in [0, 1); got {args.scans}, {args.warmup}, {args.in_flight}, "
              f"{args.latency_load}", file=sys.stderr)
        return 2
    if args.source == ANALYTIC_RAMP and not args.floor:
        print(f"dptpu bench pipeline: error: --source {ANALYTIC_RAMP} (the analytic ramp) is for --floor only; the "
              "graph's sources are raycast or a capture folder", file=sys.stderr)
        return 2
    if args.floor:
        report = {"benchmark": "pipeline-floor", "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                                                            "python": platform.python_version(),
                                                            "load_average": list(os.getloadavg())},
                  "floors": [measure_floor(step, args.size, args.source) for step in steps]}
        print(json.dumps(report, indent=1) if args.json else "\n".join(_floor_line(f) for f in report["floors"]))
        return 0
    model = dptpu_model(args.model)
    if args.dptpu_only and (args.classical_only or model is None):
        print("dptpu bench pipeline: error: --dptpu-only needs a DP-TPU model (--model, or the shipped one) and no "
              f"--classical-only; got model {model}, --classical-only {args.classical_only}", file=sys.stderr)
        return 2
    models = ([] if args.dptpu_only else ["none"]) + ([model] if model and not args.classical_only else [])
    results = []
    for step in steps:
        for which in models:
            results.append(run_configuration(steps=step, model=which, size=args.size, scans=args.scans,
                                             warmup=args.warmup, in_flight=args.in_flight,
                                             latency_load=args.latency_load, timeout_s=args.timeout,
                                             source=args.source, frame_bursts=args.frames == "bursts",
                                             trigger_bursts=args.triggers == "bursts"))
            if not args.json:
                r = results[-1]
                print(f"{r['configuration']:<28} {r['scans_per_s']:7.2f} scans/s  "
                      f"latency p50 {r['latency_ms_p50']:7.1f} "
                      f"ms  p99 {r['latency_ms_p99']:7.1f} ms  camera_limit_ratio {r['camera_limit_ratio']:.3f} "
                      f"({r['scans_timed']} scans, {r['scans_failed']} failed, {r['scans_lost']} lost)", flush=True)
        if not args.no_floor:  # the floor beside the graph, in the same run (after this step count's graph runs)
            floor = measure_floor(step, args.size, args.source)
            for r in results:
                if r["frames_per_scan"] == 2 * step:
                    attach_floor(r, floor)
            if not args.json:
                print(_floor_line(floor) + "; graph CPU / floor: " + ", ".join(
                    f"{r['configuration']} {r['cpu_over_floor']:.2f}" for r in results
                    if r["frames_per_scan"] == 2 * step and r.get("cpu_over_floor") is not None), flush=True)
    report = {"benchmark": "pipeline", "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                                                   "python": platform.python_version(),
                                                   "load_average": list(os.getloadavg())},
              "size": args.size, "dptpu_model": model, "configurations": results}
    if args.json:
        print(json.dumps(report, indent=1))
    elif model is None:
        print("DP-TPU: no model (models/dptpu.onnx not shipped, no --model): classical only")
    return 0


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--size", default="640x480", help="camera size WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--scans", type=int, default=60, help="timed scans per run (default 60)")
    parser.add_argument("--warmup", type=int, default=10, help="scans before timing starts (default 10)")
    parser.add_argument("--in-flight", type=int, default=4,
                        help="throughput run: scans started ahead of the last one reported (default 4)")
    parser.add_argument("--latency-load", type=float, default=0.5,
                        help="latency run: the projector's own scans at this fraction of the measured throughput "
                             "(default 0.5; 0 = no latency run, latencies of the throughput run)")
    parser.add_argument("--steps", default="12,3", help="sequences: 12 (2 x 12-step), 3 (2 x 3-step); default 12,3")
    parser.add_argument("--model", default=None, help="DP-TPU .onnx model (default: the shipped one, if any)")
    parser.add_argument("--source", default="raycast",
                        help="the sim node's source: raycast (default: renders random:1 and random:2 live, needs "
                             "open3d) or a folder of dptpu-capture/1 captures of the size and sequences asked (a "
                             "machine without open3d: `dptpu sim render` them elsewhere); the floor works on the "
                             "first of the same scenes (--floor also takes 'ramp': an analytic steep plane)")
    parser.add_argument("--frames", choices=("bursts", "single"), default="bursts",
                        help="how the sim hands frames to the phase node: an entry's frames in one FringeBurst "
                             "(default, as launch/sim_rig.yaml) or a FringeFrame a pattern (frame_bursts:=false)")
    parser.add_argument("--triggers", choices=("bursts", "single"), default="bursts",
                        help="how the projector hands Triggers to the sim: an entry's in one TriggerBurst (default, "
                             "as launch/sim_rig.yaml) or a Trigger a pattern (trigger_bursts:=false)")
    parser.add_argument("--classical-only", action="store_true", help="skip DP-TPU even when a model exists")
    parser.add_argument("--dptpu-only", action="store_true",
                        help="DP-TPU only (no classical run): with a timeout per invocation, a slow configuration "
                             "cannot cost the others' figures")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per launch (default 600)")
    parser.add_argument("--no-floor", action="store_true",
                        help="do not measure the floor beside the graph (measured by default, after each step count)")
    parser.add_argument("--floor", action="store_true",
                        help="no graph: the CPU per scan of the work no graph can take away (frames in, phase, "
                             "unwrap, triangulation, cloud and depth out), in one process")


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``dptpu bench pipeline``."""
    parser = argparse.ArgumentParser(prog="dptpu bench pipeline", description=__doc__.split("\n")[0])
    add_arguments(parser)
    return parser


def main(argv=None) -> int:
    """``dptpu bench pipeline ARGS`` / ``python benchmarks/pipeline_bench.py ARGS``; the exit code."""
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
