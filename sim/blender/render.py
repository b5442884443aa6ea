"""Render fringe frames of a scene with Blender (Cycles, CPU) through the rig's calibrated models.

:func:`render_frames` is what ``dptpu.sim.render.render_capture(..., engine='blender')`` calls: it writes a job
folder (``job.json`` + ``.npy`` arrays), runs :mod:`dptpu.sim.blender.worker` under the Blender environment's
Python (:mod:`dptpu.sim.blender.environment`), reads the frames back and resamples them into the real camera
(:mod:`dptpu.sim.blender.camera_warp`).

Radiometry: the projector is a point source of power ``P = 4 pi d_ref^2`` (W, with lengths in metres), so the
irradiance of pattern level 1 at ``d_ref`` (the distance from the projector to the rig's working point,
:func:`dptpu.sim.rig.working_point`) on a surface facing it is 1 W/m^2; frames are ``pi`` times Blender's radiance.
A white Lambertian surface at ``d_ref`` facing the projector under level 1 therefore reads 1.0, and in general a
Lambertian pixel reads ``albedo * level * cos(incidence) * (d_ref / d)^2 + albedo * ambient`` (plus
interreflections and the specular lobe, which Cycles renders too).
"""
from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.sim.blender_params import camera_parameters, projector_parameters
from dptpu.sim.rig import working_point
from dptpu.sim.scene_mesh import SceneMesh

from .camera_warp import RenderCamera, render_camera, warp_to_device
from .environment import blender_python

__all__ = ["BlenderRender", "BlenderWorkerError", "render", "render_frames"]

_WORKER = Path(__file__).with_name("worker.py")
_INTERPOLATIONS = ("Linear", "Closest")
#: Sensor width of the rendered camera; only lens / sensor matters, and Blender clamps widths below 1 mm.
_SENSOR_WIDTH_MM = 36.0


class BlenderWorkerError(RuntimeError):
    """The Blender worker process failed or ran out of time; the message holds the tail of its log."""


@dataclass(frozen=True)
class BlenderRender:
    """Frames rendered by Blender and what it took.

    Attributes
    ----------
    frames : ndarray (N, H, W) float32
        Linear frames in the real camera (module docstring for their scale).
    render_camera : RenderCamera
        The ideal pinhole Blender rendered before resampling.
    seconds_per_frame : list of float
        Blender's time for each frame (render and read back).
    setup_s : float
        Worker start-up: import bpy, build the scene.
    wall_s : float
        The whole call, job writing and resampling included.
    cpu_s : float
        CPU time (user + system, all threads) of the worker process: a measure of the work that does not depend
        on what else the machine runs.
    stats : dict
        The worker's ``stats.json``.
    """

    frames: np.ndarray
    render_camera: RenderCamera
    seconds_per_frame: list = field(default_factory=list)
    setup_s: float = 0.0
    wall_s: float = 0.0
    cpu_s: float = 0.0
    stats: dict = field(default_factory=dict)


def render_frames(rig: Rig, meshes, patterns, *, samples: int = 16, seed: int = 0, ambient: float = 0.0,
                  timeout_s: float | None = None) -> np.ndarray:
    """One Blender frame per projector pattern, (N, H, W) float32 linear radiance (:func:`render`)."""
    return render(rig, meshes, patterns, samples=samples, seed=seed, ambient=ambient, timeout_s=timeout_s).frames


def render(rig: Rig, meshes, patterns, *, samples: int = 16, seed: int = 0, ambient: float = 0.0,
           timeout_s: float | None = None, max_bounces: int = 4, threads: int | None = None,
           interpolation: str = "Linear", env_dir=None, keep_job: str | os.PathLike | None = None) -> BlenderRender:
    """Render one frame per projector pattern with Blender's Cycles.

    Parameters
    ----------
    rig : Rig
        Camera and projector (the projector's ``K``, skew and distortion are exact; the camera's are applied by
        resampling, :mod:`dptpu.sim.blender.camera_warp`).
    meshes : sequence of SceneMesh, or an object with a ``meshes`` attribute
        The scene, in the rig's world frame and units.
    patterns : ndarray (N, Hp, Wp)
        Projector images in [0, 1] at the projector's resolution (``rig.projector.size``), linear levels.
    samples : int
        Cycles samples per pixel (>= 1). The pixel filter is a 1-pixel box (the sensor integrates over its pixel),
        so few samples leave noise in the projector coordinate: about 0.08 projector pixels (std) at 4 samples and
        160x120 on the nominal rig with 8 steps, 0.021 at 16.
    seed : int
        Frame ``n`` renders with Cycles seed ``seed + n``: independent sampling noise per frame, as a camera's
        (reusing one seed for every frame gives every frame the same sample points, which makes the decoded phase
        2x noisier and biased); the same ``seed`` gives the same frames.
    ambient : float
        Ambient level: a Lambertian pixel of albedo ``a`` in the open reads ``a * ambient`` (a uniform world light).
    timeout_s : float, optional
        Limit for the worker process; :class:`BlenderWorkerError` past it.
    max_bounces : int
        Cycles' light-path bounces (0 = direct light only).
    threads : int, optional
        Render threads (default: all cores).
    interpolation : {"Linear", "Closest"}
        How the pattern is sampled between projector pixel centres: "Linear" (a continuous pattern, as the raycast
        twin's analytic one) or "Closest" (each micromirror a flat square).
    env_dir : path-like, optional
        The Blender environment (default :func:`dptpu.sim.blender.environment.blender_env_dir`).
    keep_job : path-like, optional
        Write the job folder there and keep it (for debugging); default a temporary folder, removed.

    Returns
    -------
    BlenderRender
    """
    started = time.perf_counter()
    meshes = _check_meshes(meshes)
    patterns = _check_patterns(patterns, rig.projector)
    if int(samples) < 1:
        raise ValueError(f"samples must be >= 1; got {samples}")
    if not np.isfinite(ambient) or ambient < 0:
        raise ValueError(f"ambient must be a level >= 0; got {ambient}")
    if int(max_bounces) < 0:
        raise ValueError(f"max_bounces must be >= 0; got {max_bounces}")
    if interpolation not in _INTERPOLATIONS:
        raise ValueError(f"interpolation must be one of {', '.join(_INTERPOLATIONS)}; got {interpolation!r}")
    pinhole = render_camera(rig.camera)
    python = blender_python(env_dir)
    job_dir = Path(keep_job) if keep_job is not None else Path(tempfile.mkdtemp(prefix="dptpu-blender-"))
    job_dir.mkdir(parents=True, exist_ok=True)
    try:
        job = _write_job(job_dir, rig, meshes, patterns, pinhole, samples=int(samples), seed=int(seed),
                         ambient=float(ambient), max_bounces=int(max_bounces), threads=threads,
                         interpolation=interpolation)
        cpu_s = _run_worker(python, job_dir, timeout_s)
        raw = np.load(job_dir / job["output"])  # (N, H_r, W_r) radiance
        stats = json.loads((job_dir / "stats.json").read_text())
    finally:
        if keep_job is None:
            shutil.rmtree(job_dir, ignore_errors=True)
    frames = warp_to_device(np.pi * raw, pinhole, rig.camera)
    return BlenderRender(frames=frames.astype(np.float32), render_camera=pinhole,
                         seconds_per_frame=list(stats["seconds_per_frame"]), setup_s=float(stats["setup_s"]),
                         wall_s=time.perf_counter() - started, cpu_s=cpu_s, stats=stats)


def reference_distance(rig: Rig) -> float:
    """``d_ref``: distance from the projector's centre to the rig's working point, rig units."""
    return float(np.linalg.norm(working_point(rig) - rig.projector.center))


def _check_meshes(meshes) -> list[SceneMesh]:
    meshes = list(getattr(meshes, "meshes", meshes))
    if not meshes:
        raise ValueError("meshes: the scene is empty (give at least one SceneMesh)")
    for index, mesh in enumerate(meshes):
        if not isinstance(mesh, SceneMesh):
            raise ValueError(f"meshes[{index}] must be a SceneMesh; got {type(mesh).__name__}")
    return meshes


def _check_patterns(patterns, projector: DeviceModel) -> np.ndarray:
    patterns = np.asarray(patterns, dtype=np.float32)
    width, height = projector.size
    if patterns.ndim != 3 or patterns.shape[1:] != (height, width) or len(patterns) == 0:
        raise ValueError(f"patterns must have shape (N, {height}, {width}) (the projector's height, width) with "
                         f"N >= 1; got {patterns.shape}")
    if not np.all(np.isfinite(patterns)) or patterns.min() < 0.0 or patterns.max() > 1.0:
        raise ValueError("patterns must be finite levels in [0, 1]")
    return patterns


def _compact(patterns: np.ndarray) -> np.ndarray:
    """Patterns (N, Hp, Wp) as one row (N, 1, Wp) when every row is the same (vertical fringes), one column
    (N, Hp, 1) when every column is, else unchanged: the worker extends them over the panel."""
    if np.array_equal(patterns, np.broadcast_to(patterns[:, :1, :], patterns.shape)):
        return np.ascontiguousarray(patterns[:, :1, :])
    if np.array_equal(patterns, np.broadcast_to(patterns[:, :, :1], patterns.shape)):
        return np.ascontiguousarray(patterns[:, :, :1])
    return patterns


def _pose(entry, scale_to_m: float) -> dict:
    return {"location_m": [float(v) * scale_to_m for v in entry.location],
            "rotation_euler_rad": [float(a) for a in entry.rotation_euler]}


def _write_job(job_dir: Path, rig: Rig, meshes, patterns, pinhole: RenderCamera, *, samples, seed, ambient,
               max_bounces, threads, interpolation) -> dict:
    scale = rig.scale_to_m
    camera = camera_parameters(pinhole.device(rig.camera), sensor_width_mm=_SENSOR_WIDTH_MM)
    projector = projector_parameters(rig.projector)
    d_ref_m = reference_distance(rig) * scale
    np.save(job_dir / "patterns.npy", _compact(patterns))
    mesh_entries = []
    for index, mesh in enumerate(meshes):
        names = {"vertices": f"mesh{index:03d}_vertices.npy", "triangles": f"mesh{index:03d}_triangles.npy"}
        np.save(job_dir / names["vertices"], (mesh.vertices * scale).astype(np.float64))
        np.save(job_dir / names["triangles"], mesh.triangles.astype(np.int32))
        entry = {"name": f"{index:03d}_{mesh.name}"[:60], **names, "albedo": mesh.material.albedo,
                 "roughness": mesh.material.roughness, "specular": mesh.material.specular, "ior": mesh.material.ior,
                 "texture": None, "uv": None}
        if mesh.albedo_texture is not None:
            entry["texture"], entry["uv"] = f"mesh{index:03d}_texture.npy", f"mesh{index:03d}_uv.npy"
            np.save(job_dir / entry["texture"], mesh.albedo_texture.astype(np.float32))
            np.save(job_dir / entry["uv"], mesh.uv.astype(np.float64))
        mesh_entries.append(entry)
    job = {
        "format": "dptpu-blender-job/1",
        "resolution": list(pinhole.size),
        "camera": {**_pose(camera, scale), "lens_mm": camera.lens_mm, "sensor_width_mm": camera.sensor_width_mm,
                   "shift_x": camera.shift_x, "shift_y": camera.shift_y, "clip_start_m": 1e-3,
                   "clip_end_m": 1e3},
        "projector": {**_pose(projector, scale), "spot_size_rad": projector.spot_size_rad,
                      "K": projector.K.tolist(), "dist": projector.dist.tolist(),
                      "size": list(projector.resolution), "power_w": 4.0 * np.pi * d_ref_m ** 2,
                      "interpolation": interpolation},
        "meshes": mesh_entries,
        "patterns": "patterns.npy",
        "render": {"samples": samples, "seed": seed, "max_bounces": max_bounces,
                   "threads": int(threads) if threads else (os.cpu_count() or 1),
                   "ambient_radiance": ambient / np.pi},
        "output": "frames.npy",
    }
    (job_dir / "job.json").write_text(json.dumps(job, indent=1))
    return job


def _run_worker(python: Path, job_dir: Path, timeout_s: float | None) -> float:
    """Run the worker on ``job_dir``; returns its CPU time (user + system, seconds)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    log_path = job_dir / "worker.log"
    with open(log_path, "w") as log:
        try:
            result = subprocess.run([str(python), str(_WORKER), str(job_dir)], stdout=log, stderr=subprocess.STDOUT,
                                    timeout=timeout_s, env=_worker_env())
        except subprocess.TimeoutExpired:
            raise BlenderWorkerError(f"Blender worker ran past timeout_s={timeout_s} s; log tail:\n"
                                     + _tail(log_path)) from None
    if result.returncode != 0:
        raise BlenderWorkerError(f"Blender worker failed (exit code {result.returncode}); log tail:\n"
                                 + _tail(log_path))
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _worker_env() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["PYTHONNOUSERSITE"] = "1"
    return env


def _tail(path: Path, lines: int = 15) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").strip().splitlines()[-lines:])
    except OSError:
        return "(no log)"
