"""Speed of the digital twin's raycast renderer (and, when available, its Blender renderer).

Run it as ``python benchmarks/twin_bench.py [--json] [--repeats R] [--size 640x480] [--scenes K] [--blender]`` or
as ``dptpu bench twin`` (the CLI imports this file from the source tree). Not a test: nothing here asserts a time.

What is measured, on the nominal DP-TPU-like rig (:func:`dptpu.sim.rig.nominal_rig`, camera ``--size``, projector
912x1140):

- ``raycast``: a 24-frame capture (sequences 96x12 and 1x12) of ``random_scene(rig, 0)`` (several objects and a
  background plane), split into ``trace`` (camera rays, open3d hits, float64 refinement, projector projection,
  shadow rays: :func:`dptpu.sim.raycast.trace`) and ``frames`` (image formation of the 24 frames, quantized to
  8 bits: :func:`dptpu.sim.image_formation.render_frames`); best and median of ``repeats`` runs; also the
  24 frames of the standard sphere (82k triangles).
- ``dataset``: training scenes per minute through the public API, each one ``random_scene(rig, seed)`` + ``trace``
  + the 24 frames + the ground truth (:func:`dptpu.sim.render.ground_truth`), in memory (no PNG writing), over
  ``--scenes`` seeds.
- ``blender``: with ``--blender`` and ``dptpu.sim.blender`` importable and set up, Cycles seconds per frame on the
  same scene (``--blender-samples``, default 16) and the raycast/Blender speed ratio; otherwise ``null`` with the
  reason.

Convention: times are wall-clock seconds from ``time.perf_counter``; per-frame figures divide the 24-frame
time by 24; ratios are Blender time / raycast time (above 1: raycast is faster).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np

DEFAULT_REPEATS = 3
DEFAULT_SCENES = 5
SEQUENCE = "96x12,1x12"


def _machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import open3d

    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "open3d": open3d.__version__}


def _timed(function, repeats):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return result, {"best_s": round(min(times), 4), "median_s": round(float(np.median(times)), 4)}


def _blender(rig, scene, sequences, samples: int, raycast_s_per_frame: float) -> dict:
    try:
        from dptpu.sim import blender
    except ModuleNotFoundError as exc:
        return {"seconds_per_frame": None, "raycast_blender_ratio": None, "reason": f"not importable ({exc.name})"}
    from dptpu.fpp.patterns import fringe_patterns

    patterns = fringe_patterns(frequency=96, steps=4, projector_size=rig.projector.size, dtype=float) / 255.0
    try:
        start = time.perf_counter()
        blender.render_frames(rig, scene.meshes, patterns.astype(np.float32), samples=samples, seed=0)
        elapsed = time.perf_counter() - start
    except Exception as exc:  # noqa: BLE001 -- not set up (dptpu sim setup-blender), a worker failure: report it
        return {"seconds_per_frame": None, "raycast_blender_ratio": None, "reason": f"{type(exc).__name__}: {exc}"}
    per_frame = elapsed / len(patterns)
    return {"seconds_per_frame": round(per_frame, 3), "samples": samples, "frames": len(patterns),
            "raycast_blender_ratio": round(per_frame / raycast_s_per_frame, 1),
            "note": "includes the worker start-up, shared by the frames of one call"}


def run_benchmarks(*, size=(640, 480), repeats=DEFAULT_REPEATS, scenes=DEFAULT_SCENES, blender=False,
                   blender_samples=16) -> dict:
    from dptpu.sim.image_formation import parse_sequences, render_frames
    from dptpu.sim.raycast import trace
    from dptpu.sim.render import ground_truth
    from dptpu.sim.rig import nominal_rig
    from dptpu.sim.scenes import random_scene, sphere_scene

    rig = nominal_rig(camera_size=size)
    sequences = parse_sequences(SEQUENCE)
    frames_total = sum(s.steps for s in sequences)
    report = {"machine": _machine(), "size": list(size), "frames": frames_total, "sequence": SEQUENCE,
              "repeats": repeats}
    trace(rig, sphere_scene(rig, subdivisions=2))  # warm-up: open3d import and first scene
    for name, scene in (("random_scene_0", random_scene(rig, 0)), ("sphere", sphere_scene(rig))):
        samples, trace_time = _timed(lambda scene=scene: trace(rig, scene), repeats)
        _, frames_time = _timed(lambda samples=samples: render_frames(rig, samples, sequences), repeats)
        total = trace_time["best_s"] + frames_time["best_s"]
        report[f"raycast_{name}"] = {
            "triangles": int(sum(len(m.triangles) for m in scene.meshes)), "trace": trace_time,
            "frames": frames_time, "total_best_s": round(total, 4),
            "seconds_per_frame": round(total / frames_total, 5), "frames_per_second": round(frames_total / total, 1)}

    def one_scene(seed):
        scene = random_scene(rig, seed)
        samples = trace(rig, scene)
        render_frames(rig, samples, sequences)
        ground_truth(rig, samples, sequences)

    start = time.perf_counter()
    for seed in range(scenes):
        one_scene(seed)
    elapsed = time.perf_counter() - start
    report["dataset"] = {"scenes": scenes, "seconds": round(elapsed, 3),
                         "scenes_per_minute": round(60.0 * scenes / elapsed, 1),
                         "what": f"random_scene + trace + {frames_total} frames + ground truth, in memory"}
    raycast_per_frame = report["raycast_random_scene_0"]["seconds_per_frame"]
    if blender:
        report["blender"] = _blender(rig, random_scene(rig, 0), sequences, blender_samples, raycast_per_frame)
    else:
        report["blender"] = {"seconds_per_frame": None, "raycast_blender_ratio": None,
                             "reason": "not requested (--blender)"}
    return report


def _text(report) -> str:
    m = report["machine"]
    lines = [f"machine: {m['cpu']}, {m['cores']} cores; Python {m['python']}, numpy {m['numpy']}, open3d {m['open3d']}",
             f"camera {report['size'][0]}x{report['size'][1]}, {report['frames']} frames ({report['sequence']}), "
             f"best of {report['repeats']}"]
    for key in ("raycast_random_scene_0", "raycast_sphere"):
        r = report[key]
        lines.append(f"{key}: {r['triangles']} triangles; trace {r['trace']['best_s']:.3f} s + frames "
                     f"{r['frames']['best_s']:.3f} s = {r['total_best_s']:.3f} s ({r['frames_per_second']} frames/s)")
    d = report["dataset"]
    lines.append(f"dataset: {d['scenes_per_minute']} scenes/min ({d['scenes']} scenes in {d['seconds']} s; "
                 f"{d['what']})")
    b = report["blender"]
    lines.append(f"blender: {b['seconds_per_frame']} s/frame, raycast/Blender ratio {b['raycast_blender_ratio']}"
                 + (f" ({b['reason']})" if b.get("reason") else ""))
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description="speed of the twin's raycast renderer (docs/benchmarks.md)")
    add_arguments(parser)
    return parser


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--repeats", type=int, default=None, help=f"timed runs (default {DEFAULT_REPEATS})")
    parser.add_argument("--size", default=None, help="camera size WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--scenes", type=int, default=None, help=f"dataset scenes timed (default {DEFAULT_SCENES})")
    parser.add_argument("--blender", action="store_true", help="also time dptpu.sim.blender (needs setup-blender)")
    parser.add_argument("--blender-samples", type=int, default=16, help="Cycles samples per pixel (default 16)")


def run(args) -> int:
    """Run with parsed ``args`` (``json``, ``repeats``, ``size``, ``scenes``, ``blender``, ``blender_samples``);
    prints the report; 0."""
    from dptpu.sim.rig import parse_size

    repeats = args.repeats or DEFAULT_REPEATS
    scenes = args.scenes or DEFAULT_SCENES
    if repeats < 1 or scenes < 1:
        raise ValueError(f"--repeats and --scenes must be >= 1; got {repeats}, {scenes}")
    size = parse_size(args.size) if args.size else (640, 480)
    report = run_benchmarks(size=size, repeats=repeats, scenes=scenes, blender=getattr(args, "blender", False),
                            blender_samples=getattr(args, "blender_samples", 16))
    print(json.dumps(report, indent=2) if args.json else _text(report))
    return 0


if __name__ == "__main__":
    sys.exit(run(build_parser().parse_args()))
