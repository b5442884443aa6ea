"""``dptpu bench pipeline``: the whole scanner graph end to end, scans per second and latency (not a test).

Each configuration runs ``launch/sim_rig.yaml`` as real processes (projector on the emulated trigger box, sim,
phase, unwrap, cloud, scan monitor) with the sim as fast as possible (no frame-rate limit, 100 us per pattern on
the emulated box), ``--in-flight`` scans started ahead of the last one reported (scan on demand, so the graph
is never overrun), ground truth off (the monitor only times). After ``--warmup`` scans, ``--scans`` scans are
timed:

- ``scans_per_s``: ``(n - 1) / (t_n - t_1)`` over the clouds' arrival times at the monitor;
- ``latency_ms_p50`` / ``latency_ms_p99``: from the scan's last Trigger (the stamp its frames and cloud carry)
  to its cloud's arrival at the monitor; ``latency_from_first_trigger_ms_p50`` adds the projection itself;
- ``node_duration_ms_p50``: each node's median ``ScanStatus.duration_s`` (where the time goes);
- ``camera_limit_ratio``: ``scans_per_s`` over what the paper's camera allows, the Basler acA640-750 at 750
  frames/s: 31.25 scans/s at 24 frames (2 x 12 steps), 125 at 6 frames (2 x 3 steps).

Configurations: 2 x 12-step (``64x12,1x12``) and 2 x 3-step (``64x3,1x3``), MF, classical and, when a DP-TPU
model is available (``dptpu.models.inference.shipped_model_path()`` or ``--model``), DP-TPU. Run::

    dptpu bench pipeline [--json] [--size 640x480] [--scans 30] [--warmup 5] [--in-flight 2] [--steps 12,3]
    python benchmarks/pipeline_bench.py [same options]

Results and the machine they were taken on: docs/benchmarks.md, "bench pipeline".
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
SIM_RIG = REPO_ROOT / "launch" / "sim_rig.yaml"
#: The paper's camera, Basler acA640-750um: frames per second at 640x480.
CAMERA_FRAMES_PER_S = 750.0
SEQUENCES = {12: "64x12,1x12", 3: "64x3,1x3"}
DOMAIN_ID = 97


def camera_limit_scans_per_s(frames_per_scan: int) -> float:
    """Scans per second the acA640-750 allows: 750 / frames (31.25 at 24 frames, 125 at 6)."""
    return CAMERA_FRAMES_PER_S / frames_per_scan


def run_configuration(*, steps: int, model: str, size: str, scans: int, warmup: int, in_flight: int,
                      timeout_s: float) -> dict:
    """Launch the sim rig for one configuration and time it; the figures of the module docstring."""
    sequence = SEQUENCES[steps]
    frames = sum(int(entry.split("x")[1]) for entry in sequence.split(","))
    folder = Path(tempfile.mkdtemp(prefix="dpb", dir="/tmp"))
    summary = folder / "summary.json"
    env = dict(os.environ, DPTPU_DISCOVERY_DIR=str(folder / "d"), DPTPU_DOMAIN_ID=str(DOMAIN_ID),
               PYTHONPATH=str(REPO_ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    command = [sys.executable, "-c", "import sys; from dptpu.cli.main import main; sys.exit(main())", "launch",
               str(SIM_RIG), f"scans:={warmup + scans}", f"size:={size}", f"sequence:={sequence}", "method:=mf",
               f"model:={model}", "ground_truth:=false", "exposure_us:=100", f"in_flight:={in_flight}", "ply_dir:=",
               f"summary:={summary}", "scenes:=random:1,random:2", "source:=raycast"]
    started = time.monotonic()
    try:
        done = subprocess.run(command, cwd=folder, env=env, capture_output=True, text=True, timeout=timeout_s)
        if done.returncode != 0 or not summary.is_file():
            raise RuntimeError(f"the sim rig exited with {done.returncode}: {done.stderr[-2000:]}")
        report = json.loads(summary.read_text())
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    records = [r for r in report["scans"] if r["outcome"] == "ok"]
    timed = records[-scans:] if len(records) > scans else records  # the monitor keeps the last 200 records
    arrivals = np.array([r["cloud_arrival_unix_s"] for r in timed])
    latency = np.array([r["latency_ms"] for r in timed])
    first = np.array([r.get("latency_from_first_trigger_ms", np.nan) for r in timed])
    scans_per_s = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0]) if len(arrivals) > 1 else float("nan")
    return {
        "configuration": f"2 x {steps}-step, {'DP-TPU' if model != 'none' else 'classical'} MF",
        "sequence": sequence, "frames_per_scan": frames, "method": "mf", "model": model, "size": size,
        "in_flight": in_flight, "scans_timed": int(len(timed)),
        "scans_failed": int(report["totals"]["failed"]), "scans_lost": int(report["totals"]["lost"]),
        "scans_per_s": round(float(scans_per_s), 3),
        "latency_ms_p50": round(float(np.percentile(latency, 50)), 1),
        "latency_ms_p99": round(float(np.percentile(latency, 99)), 1),
        "latency_from_first_trigger_ms_p50": round(float(np.nanpercentile(first, 50)), 1)
        if np.isfinite(first).any() else None,
        "node_duration_ms_p50": _node_durations_ms(timed),
        "camera_limit_scans_per_s": camera_limit_scans_per_s(frames),
        "camera_limit_ratio": round(float(scans_per_s / camera_limit_scans_per_s(frames)), 4),
        "wall_s": round(time.monotonic() - started, 1),
    }


def _node_durations_ms(records) -> dict:
    """Median ``ScanStatus.duration_s`` of each node over ``records``, ms (docs/nodes.md: phase from the scan's first
    frame's arrival, unwrap its own unwrapping, cloud from the scan's last frame to the cloud)."""
    nodes = sorted({node for r in records for node in r.get("node_durations_s", {})})
    return {node: round(1e3 * float(np.median([r["node_durations_s"][node] for r in records
                                                if node in r.get("node_durations_s", {})])), 1) for node in nodes}


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
    steps = [int(s) for s in str(args.steps).split(",")]
    if any(s not in SEQUENCES for s in steps):
        print(f"dptpu bench pipeline: error: --steps takes 12 and/or 3; got {args.steps}", file=sys.stderr)
        return 2
    if not 2 <= args.scans <= 200 or args.warmup < 0 or args.in_flight < 1:
        print("dptpu bench pipeline: error: --scans must be 2..200 (the monitor keeps 200 records), --warmup >= 0, "
              f"--in-flight >= 1; got {args.scans}, {args.warmup}, {args.in_flight}", file=sys.stderr)
        return 2
    model = dptpu_model(args.model)
    models = ["none"] + ([model] if model and not args.classical_only else [])
    results = []
    for step in steps:
        for which in models:
            results.append(run_configuration(steps=step, model=which, size=args.size, scans=args.scans,
                                             warmup=args.warmup, in_flight=args.in_flight, timeout_s=args.timeout))
            if not args.json:
                r = results[-1]
                print(f"{r['configuration']:<28} {r['scans_per_s']:7.2f} scans/s  "
                      f"latency p50 {r['latency_ms_p50']:7.1f} "
                      f"ms  p99 {r['latency_ms_p99']:7.1f} ms  camera_limit_ratio {r['camera_limit_ratio']:.3f} "
                      f"({r['scans_timed']} scans)", flush=True)
    report = {"benchmark": "pipeline", "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                                                   "python": platform.python_version(),
                                                   "load_average": list(os.getloadavg())},
              "size": args.size, "dptpu_model": model, "configurations": results}
    if args.json:
        print(json.dumps(report, indent=1))
    elif model is None:
        print("DP-TPU: no model (dptpu/models/dptpu.onnx not shipped, no --model): classical only")
    return 0


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--size", default="640x480", help="camera size WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--scans", type=int, default=30, help="timed scans per configuration (default 30)")
    parser.add_argument("--warmup", type=int, default=5, help="scans before timing starts (default 5)")
    parser.add_argument("--in-flight", type=int, default=2, help="scans started ahead (default 2)")
    parser.add_argument("--steps", default="12,3", help="sequences: 12 (2 x 12-step), 3 (2 x 3-step); default 12,3")
    parser.add_argument("--model", default=None, help="DP-TPU .onnx model (default: the shipped one, if any)")
    parser.add_argument("--classical-only", action="store_true", help="skip DP-TPU even when a model exists")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per configuration (default 600)")


if __name__ == "__main__":
    main_parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_arguments(main_parser)
    sys.exit(run(main_parser.parse_args()))
