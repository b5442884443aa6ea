"""Speed of ``dptpu.fpp`` against plain references, each pair timed side by side in one run.

Run it as ``python benchmarks/fpp_bench.py [--json] [--repeats R] [--size 640x480]`` or as
``dptpu bench fpp`` (the CLI imports this file from the source tree). Not a test: nothing here asserts a
time; every pair is also checked to give the same numbers, and the report says how close they are.

What is measured (camera images of ``--size``, default 640x480):

- ``phase``: wrapped phase of 24 frames, two 12-step sequences of the multi-wavelength pair
  ``f = 48, 47``, by :func:`dptpu.fpp.phase.wrapped_phase` (Eq. (2) of the paper) against OpenCV
  contrib's ``cv2.structured_light`` SinusoidalPattern, method PSP, ``computePhaseMap``. OpenCV's PSP
  reads exactly 3 frames shifted by ``+2*pi/3``, so the 24 frames are split into 8 disjoint 3-frame
  sets (frames ``n, n+8, n+4`` of each sequence, ``n = 0..3``): OpenCV's 24-frame time is the measured
  total of those 8 calls (8 x its time per set). Ours is also timed on the same 8 sets (like for like).
- ``unwrap``: :func:`dptpu.fpp.tpu.unwrap_mf` / ``unwrap_mw`` / ``unwrap_nt`` against the bare
  equations written here in numpy (Eqs. (5), (6)-(7), and for NT a per-pixel search over the table of
  reachable fringe-order pairs ``(k_h, k_l)``, vectorized as an argmin over the pairs).
- ``triangulate``: :class:`dptpu.fpp.triangulate.Triangulator` (precompute once, then
  ``points(coord)`` for the whole image) against the per-pixel 3x3 solve
  :func:`dptpu.fpp.triangulate.triangulate_reference`, which is timed on a subset of pixels and scaled
  linearly to the full image.

- ``node_paths``: the hot paths of the scanner graph's nodes, per 640x480 scan, against the previous
  implementations written out here (``before``): the phase node's 24 frames (wrapped phase, modulation,
  quality mask, float32 maps) against float64 ``tensordot`` + ``arctan2``; the unwrap node's MW call on
  float32 phases with a validity mask; the cloud node's triangulation on a rig with the projector and
  camera distortion of the real sphere calibration (projector ``k2 = 6.28``: up to 26 px of distortion),
  against the whole-image fixed point (6 iterations of triangulate, project, re-distort), each followed by
  the cloud node's camera-frame float32 metres; ours also through ``Triangulator.camera_points``.
  Times here also carry ``best_cpu_ms`` (``time.process_time``: the CPU the process used, which on a
  loaded machine is closer to the idle-core time than the wall clock).

The scene is synthetic and seeded: a camera 640x480 (fx = 2600 px, intrinsics scaled with ``--size``)
at the origin looking along +z, a 912x1140 projector (fx = 1730 px, fy = 3460 px) 170 mm to its right
turned 6.21 deg towards it (the paper's rig), both with small lens distortion, looking at a tilted plane
about 1 m away with a smooth bump. Fringe images follow the project convention
``I_n = A + B cos(phi - 2*pi*n/N)``, ``phi = 2*pi*f*x_p/W``, with Gaussian noise, rounded to uint8.

Convention: times are wall-clock milliseconds from ``time.perf_counter``; each figure is the best
(and the median) of ``repeats`` runs; a ratio is ``reference time / our time`` from the best times, so a
ratio above 1 means ours is faster.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import tracemalloc

import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.fpp.phase import quality_mask, wrapped_phase
from dptpu.fpp.tpu import unwrap, unwrap_mf, unwrap_mw, unwrap_nt
from dptpu.fpp.triangulate import Triangulator, camera_rays, projector_coordinate, triangulate_reference

TWO_PI = 2.0 * np.pi

#: The paper's projector (DLP 4500) and camera (Basler acA640-750um), pixels.
PROJECTOR_SIZE = (912, 1140)
CAMERA_SIZE = (640, 480)
STEPS = 12
#: High frequency and the low frequency of each TPU method (the paper's S4 set includes 48; its MF, MW
#: and NT partners are 1, 47 and 10.9). 48 keeps OpenCV's fixed 42x42 band-pass window inside the
#: spectrum down to a 96 px wide image (64 would need >= 104 px).
F_HIGH = 48.0
F_LOW = {"mf": 1.0, "mw": 47.0, "nt": 10.9}
NOISE_DN = 0.5  # Gaussian sensor noise, digital numbers (8-bit)
BORDER_PX_FRACTION = 0.05  # OpenCV's DFT band-pass smears the image borders; agreement excludes them
#: Agreement bounds checked by the benchmark (and the CLI test).
PHASE_SAME_SETS_RMS_BOUND_RAD = 0.05  # a convention slip (sign, offset, frame order) gives ~1.8 rad
TRIANGULATION_BOUND_MM = 1e-6
DEFAULT_REPEATS = 5
DEFAULT_SUBSET_PIXELS = 2000
#: Lens distortion (k1 k2 p1 p2 k3) of the real sphere calibration (``CamCalibResult_real.mat``,
#: ``PrjCalibResult_real.mat``, rounded): the node-path triangulation runs on a rig with these.
REAL_LIKE_CAMERA_DIST = (-0.1289, -0.5635, -0.00138, -0.00038, 0.0)
REAL_LIKE_PROJECTOR_DIST = (-0.0494, 6.279, 0.00098, 0.00113, 0.0)
#: Phase node parameters (its defaults): smallest modulation of a valid pixel, DN; the uint8 saturation level.
NODE_MIN_MODULATION_DN = 5.0
NODE_SATURATION_DN = 255
FIXED_POINT_ITERATIONS = 6  # the previous Triangulator's projector-distortion iterations
#: Node-path agreement bounds: float32 phase (measured 5e-7 rad), float32 metres (1e-7 relative), the
#: Newton triangulation against the converged fixed point (measured 3e-12 mm).
NODE_PHASE_BOUND_RAD = 1e-5
NODE_POINTS_BOUND_MM = 1e-6
NODE_METRES_RELATIVE_BOUND = 1e-6


# --------------------------------------------------------------------------------------------
# Synthetic rig, scene and images
# --------------------------------------------------------------------------------------------


def make_rig(camera_size=CAMERA_SIZE, *, camera_dist=(-0.08, 0.12, 0.0004, -0.0003, 0.0),
             projector_dist=(0.02, -0.04, 0.0003, 0.0002, 0.0)) -> Rig:
    """The benchmark rig: camera at the origin looking +z, projector 170 mm to the right, 6.21 deg toe-in.

    Parameters
    ----------
    camera_size : (int, int)
        Camera ``(width, height)`` in pixels; the 640x480 intrinsics (fx = fy = 2600 px) are scaled by
        ``width / 640`` so every size sees the same field of view.
    camera_dist, projector_dist : sequence of 5 float
        ``k1 k2 p1 p2 k3`` of each device; small by default, :data:`REAL_LIKE_PROJECTOR_DIST` etc. for the
        node-path triangulation.

    Returns
    -------
    Rig
        Units mm; world frame = camera frame.

    Convention: pixel centres are 0-based, so the principal point of a W x H camera is
    ``((W - 1)/2, (H - 1)/2)``; ``X_dev = R @ X_world + T``.
    """
    width, height = camera_size
    scale = width / CAMERA_SIZE[0]
    camera = DeviceModel(
        K=[[2600.0 * scale, 0.0, (width - 1) / 2.0], [0.0, 2600.0 * scale, (height - 1) / 2.0], [0, 0, 1]],
        dist=list(camera_dist),
        R=np.eye(3),
        T=np.zeros(3),
        size=(width, height),
    )
    angle = np.radians(6.21)
    c, s = np.cos(angle), np.sin(angle)
    R_p = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # optical axis turned towards -x
    projector = DeviceModel(
        K=[[1730.0, 0.0, (PROJECTOR_SIZE[0] - 1) / 2.0], [0.0, 3460.0, (PROJECTOR_SIZE[1] - 1) / 2.0], [0, 0, 1]],
        dist=list(projector_dist),
        R=R_p,
        T=-R_p @ np.array([170.0, 0.0, 0.0]),
        size=PROJECTOR_SIZE,
    )
    return Rig(camera=camera, projector=projector, units="mm")


def make_scene(rig: Rig) -> dict:
    """Ground truth of the synthetic scene seen by every camera pixel.

    The surface is ``z = 1000 + 0.12 x - 60 exp(-((x - 10)^2 + (y + 5)^2) / (2 * 45^2))`` mm (a tilted
    plane with a bump towards the camera), intersected with each pixel's distorted ray by fixed-point
    iteration on the depth.

    Returns
    -------
    dict
        ``points`` (H, W, 3) mm, ``projector_x`` (H, W) measured (distorted) projector column in
        pixels, ``background`` ``A`` and ``modulation`` ``B`` (H, W) in 8-bit digital numbers.
    """
    rays = camera_rays(rig.camera)  # (H, W, 3), unit, camera frame = world
    x_n = rays[..., 0] / rays[..., 2]  # (H, W) undistorted normalized coordinates
    y_n = rays[..., 1] / rays[..., 2]
    depth = np.full(x_n.shape, 1000.0)
    for _ in range(40):  # contraction: |dz/dx * x_n| < 0.2
        x, y = x_n * depth, y_n * depth
        depth = 1000.0 + 0.12 * x - 60.0 * np.exp(-((x - 10.0) ** 2 + (y + 5.0) ** 2) / (2.0 * 45.0**2))
    points = np.stack([x_n * depth, y_n * depth, depth], axis=-1)  # (H, W, 3)

    # Projected with the distortion written out here, independently of dptpu.fpp.distortion (under test).
    projector = rig.projector
    X_prj = points @ projector.R.T + projector.T  # (H, W, 3)
    xy = X_prj[..., :2] / X_prj[..., 2:3]
    k1, k2, p1, p2, k3 = projector.dist
    r2 = (xy**2).sum(axis=-1)
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    x_d = xy[..., 0] * radial + 2.0 * p1 * xy[..., 0] * xy[..., 1] + p2 * (r2 + 2.0 * xy[..., 0] ** 2)
    projector_x = projector.K[0, 0] * x_d + projector.K[0, 2]  # (H, W), zero skew

    height, width = x_n.shape
    v, u = np.mgrid[0:height, 0:width] / np.array([max(height - 1, 1), max(width - 1, 1)])[:, None, None]
    background = 125.0 + 10.0 * np.sin(2.0 * np.pi * (0.7 * u + 0.4 * v))  # (H, W) DN
    modulation = 90.0 * (0.85 + 0.15 * np.cos(2.0 * np.pi * (0.5 * u - 0.8 * v)))  # (H, W) DN
    return {"points": points, "projector_x": projector_x, "background": background, "modulation": modulation}


def fringe_images(scene: dict, frequency: float, steps: int, rng) -> np.ndarray:
    """Camera images (N, H, W) uint8 of an N-step sequence of ``frequency`` on the scene.

    ``I_n = round(A + B cos(phi - 2*pi*n/N) + noise)``, ``phi = 2*pi*f*x_p/W`` (Eq. (1) of the paper),
    Gaussian noise of ``NOISE_DN`` digital numbers, clipped to [0, 255].
    """
    phi = TWO_PI * frequency * scene["projector_x"] / PROJECTOR_SIZE[0]  # (H, W)
    shifts = TWO_PI * np.arange(steps) / steps  # (N,)
    levels = scene["background"] + scene["modulation"] * np.cos(phi[None] - shifts[:, None, None])
    levels += rng.normal(0.0, NOISE_DN, levels.shape)
    return np.clip(np.rint(levels), 0, 255).astype(np.uint8)


# --------------------------------------------------------------------------------------------
# References: the bare equations, without checks, masks or reliability
# --------------------------------------------------------------------------------------------


def reference_mf(psi_h, psi_l, f_h, f_l):
    """Eq. (5) of the paper: ``k_h = Round[(f_h psi_l - f_l psi_h) / (2 pi f_l)]``; returns (k_h, Psi_h)."""
    k_h = np.round((f_h * psi_l - f_l * psi_h) / (TWO_PI * f_l))
    return k_h, psi_h + TWO_PI * k_h


def reference_mw(psi_h, psi_l, f_h, f_l):
    """Eqs. (6)-(7): ``psi_eq = mod(psi_h - psi_l, 2 pi)``, then Eq. (5) against ``f_eq = f_h - f_l``."""
    f_eq = f_h - f_l
    psi_eq = np.mod(psi_h - psi_l, TWO_PI)
    k_h = np.round((f_h * psi_eq - f_eq * psi_h) / (TWO_PI * f_eq))
    return k_h, psi_h + TWO_PI * k_h


def reference_nt_pairs(f_h, f_l, extent):
    """Every fringe-order pair ``(k_h, k_l)`` that some projector coordinate ``0 <= x < extent`` has.

    The pair only changes at multiples of the periods ``extent/f_h`` and ``extent/f_l``; the pair of
    each interval between consecutive breakpoints is read at its midpoint. Returns two int arrays (P,).
    """
    period_h, period_l = extent / f_h, extent / f_l
    breakpoints = np.union1d(period_h * np.arange(np.ceil(f_h)), period_l * np.arange(np.ceil(f_l)))
    breakpoints = breakpoints[breakpoints < extent]
    midpoints = (breakpoints + np.append(breakpoints[1:], extent)) / 2.0
    return np.floor(midpoints / period_h).astype(np.int64), np.floor(midpoints / period_l).astype(np.int64)


def reference_nt(psi_h, psi_l, f_h, f_l, extent, *, rows_per_block=32):
    """Number-theoretic TPU by brute force: each pixel takes the pair ``(k_h, k_l)`` whose two projector
    coordinates ``(psi_h/2pi + k_h) extent/f_h`` and ``(psi_l/2pi + k_l) extent/f_l`` agree best
    (argmin of their distance over the pair table; Eqs. (8)-(9) without the integer key).

    Vectorized over (pairs, pixels) in blocks of rows to bound memory. Returns (k_h, Psi_h).
    """
    k_h_table, k_l_table = reference_nt_pairs(f_h, f_l, extent)
    period_h, period_l = extent / f_h, extent / f_l
    k_h = np.empty(psi_h.shape, dtype=np.int64)
    for start in range(0, psi_h.shape[0], rows_per_block):  # blocks of rows, not pixels
        block = slice(start, start + rows_per_block)
        x_h = (psi_h[block][None] / TWO_PI + k_h_table[:, None, None]) * period_h  # (P, rows, W)
        x_l = (psi_l[block][None] / TWO_PI + k_l_table[:, None, None]) * period_l  # (P, rows, W)
        best = np.argmin(np.abs(x_h - x_l), axis=0)  # (rows, W)
        k_h[block] = k_h_table[best]
    return k_h, psi_h + TWO_PI * k_h


def reference_phase_node(stack, min_modulation, saturation_level):
    """The phase node's work on one N-step stack as it was: Eq. (2) in float64 by ``tensordot``, ``arctan2``,
    ``hypot``, ``mean``, the mask by ``any(stack >= level)``, then float32 maps.

    Returns (phase float32 in [0, 2pi), modulation float32, valid bool), each (H, W).
    """
    steps = stack.shape[0]
    delta = -TWO_PI * np.arange(steps) / steps  # (N,)
    frames = stack.astype(np.float64)  # (N, H, W)
    s = -np.tensordot(np.sin(delta), frames, axes=(0, 0))
    c = np.tensordot(np.cos(delta), frames, axes=(0, 0))
    phase = np.mod(np.arctan2(s, c), TWO_PI)
    phase[phase >= TWO_PI] = 0.0
    modulation = (2.0 / steps) * np.hypot(s, c)
    frames.mean(axis=0)  # the background, computed (and dropped by the node) as before
    valid = (modulation >= min_modulation) & ~np.any(stack >= saturation_level, axis=0)
    phase32 = phase.astype(np.float32)
    return np.where(phase32 >= TWO_PI, np.float32(0.0), phase32), modulation.astype(np.float32), valid


def reference_points_fixed_point(rig, rays, coord, axis=0, iterations=FIXED_POINT_ITERATIONS):
    """Whole-image triangulation as it was: the plane of the measured coordinate, then ``iterations`` passes
    of project into the projector, re-distort, move the ideal coordinate by the miss, re-intersect.

    ``rays`` (H, W, 3) are the undistorted unit camera rays (world); returns world points (H, W, 3).
    """
    projector = rig.projector
    P = projector.projection_matrix
    a, b = P[axis], P[2]
    origin = rig.camera.center
    alpha, beta = a @ np.append(origin, 1.0), b @ np.append(origin, 1.0)
    gamma, delta = rays @ a[:3], rays @ b[:3]  # (H, W)

    def on_plane(c):
        with np.errstate(divide="ignore", invalid="ignore"):
            return origin + ((c * beta - alpha) / (gamma - c * delta))[..., None] * rays

    ideal = coord
    points = on_plane(ideal)
    k1, k2, p1, p2, k3 = projector.dist
    for _ in range(iterations):
        X = points @ projector.R.T + projector.T  # (H, W, 3)
        x, y = X[..., 0] / X[..., 2], X[..., 1] / X[..., 2]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        x_d = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        y_d = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        measured = (projector.K[0, 0] * x_d + projector.K[0, 1] * y_d + projector.K[0, 2] if axis == 0
                    else projector.K[1, 1] * y_d + projector.K[1, 2])
        ideal = ideal + (coord - measured)
        points = on_plane(ideal)
    return points


def cloud_node_metres(rig, world):
    """The cloud node's step after triangulation: camera frame, metres, NaN unless z > 0, float32 (H, W, 3)."""
    camera = (world @ rig.camera.R.T + rig.camera.T) * rig.scale_to_m
    with np.errstate(invalid="ignore"):
        camera[~(camera[..., 2] > 0)] = np.nan
    return camera.astype(np.float32)


# --------------------------------------------------------------------------------------------
# Timing
# --------------------------------------------------------------------------------------------


def time_call(function, repeats, *, cpu=False):
    """Run ``function()`` once untimed (warm-up: caches, thread pools), then ``repeats`` timed times.

    Returns ({"best_ms", "median_ms"}, result of the last call); with ``cpu`` also ``"best_cpu_ms"``, the
    least process CPU time (``time.process_time``, all threads) of a run.
    """
    result = function()
    times_ms, cpu_ms = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = function()
        times_ms.append((time.perf_counter() - start) * 1e3)
        cpu_ms.append((time.process_time() - start_cpu) * 1e3)
    timing = {"best_ms": float(np.min(times_ms)), "median_ms": float(np.median(times_ms))}
    if cpu:
        timing["best_cpu_ms"] = float(np.min(cpu_ms))
    return timing, result


def peak_memory_mib(function) -> float:
    """Peak memory (MiB) that numpy/Python allocate during one ``function()`` call (tracemalloc).

    Allocations made inside OpenCV's C++ code are invisible to tracemalloc, so OpenCV is not measured.
    """
    tracemalloc.start()
    try:
        function()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return peak / 2**20


def _ratio(reference: dict, ours: dict) -> float:
    return reference["best_ms"] / ours["best_ms"] if ours["best_ms"] > 0 else float("inf")


def _circular_difference(a, b):
    """``a - b`` wrapped into ``[-pi, pi)``, radians."""
    return np.mod(a - b + np.pi, TWO_PI) - np.pi


# --------------------------------------------------------------------------------------------
# Benchmarks
# --------------------------------------------------------------------------------------------


def opencv_psp():
    """OpenCV contrib's SinusoidalPattern configured for PSP, or raise RuntimeError naming what is missing."""
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - opencv is a dependency
        raise RuntimeError(f"OpenCV is not installed ({exc}); install opencv-contrib-python-headless") from None
    structured_light = getattr(cv2, "structured_light", None)
    if structured_light is None or not hasattr(structured_light, "SinusoidalPattern"):
        raise RuntimeError(
            f"this OpenCV {cv2.__version__} has no cv2.structured_light.SinusoidalPattern; "
            "install opencv-contrib-python-headless"
        )
    # OpenCV 4.x exposes the parameters as SinusoidalPattern_Params, 5.x as SinusoidalPattern.Params.
    params_class = getattr(structured_light, "SinusoidalPattern_Params", None) or getattr(
        structured_light.SinusoidalPattern, "Params", None
    )
    if params_class is None:
        raise RuntimeError(f"OpenCV {cv2.__version__}: no SinusoidalPattern parameters class found")
    return cv2, structured_light, params_class


def bench_phase(images_high, images_low, phi_high, repeats) -> dict:
    """Wrapped phase of 24 frames (two 12-step sequences): ours against OpenCV's PSP on 3-frame sets.

    ``phi_high`` (H, W) is the true absolute phase of ``images_high`` (radians), for the accuracy figures.
    """
    cv2, structured_light, params_class = opencv_psp()
    steps, height, width = images_high.shape
    params = params_class()
    params.width, params.height = width, height
    params.nbrOfPeriods = int(round(F_HIGH))  # used by generate() only; computePhaseMap finds the peak
    params.setMarkers = False
    params.horizontal = False
    params.methodId = structured_light.PSP
    pattern = structured_light.SinusoidalPattern.create(params)

    sequences = [images_high, images_low]
    # 3-frame sets with OpenCV's +2*pi/3 shift: frames n, n+8, n+4 have shifts -2*pi*n/12 + j*2*pi/3.
    set_steps = steps // 3
    sets = []  # (sequence index, n, [3 frames])
    for index, images in enumerate(sequences):
        for n in range(set_steps):
            frames = [np.ascontiguousarray(images[(n + 2 * set_steps * j) % steps]) for j in range(3)]
            sets.append((index, n, frames))
    set_stacks = [np.stack(frames) for _, _, frames in sets]  # (3, H, W) each, for ours

    ours_24, ours_maps = time_call(lambda: [wrapped_phase(images) for images in sequences], repeats)
    opencv_24, opencv_maps = time_call(
        lambda: [pattern.computePhaseMap(frames)[0] for _, _, frames in sets], repeats
    )
    ours_sets, ours_set_maps = time_call(
        lambda: [wrapped_phase(stack, shift_sign=1).phase for stack in set_stacks], repeats
    )

    border = max(1, int(round(BORDER_PX_FRACTION * min(width, height))))
    interior = (slice(border, height - border), slice(border, width - border))
    same_sets = np.stack([_circular_difference(np.asarray(cv_map, dtype=np.float64), ours_map)
                          for cv_map, ours_map in zip(opencv_maps, ours_set_maps)])  # (8, H, W)
    vs_12_step = np.stack([
        _circular_difference(np.asarray(cv_map, dtype=np.float64) + TWO_PI * n / steps, ours_maps[index].phase)
        for cv_map, (index, n, _) in zip(opencv_maps, sets)
    ])  # (8, H, W)
    same_inner = np.abs(same_sets[(slice(None),) + interior])
    vs_inner = np.abs(vs_12_step[(slice(None),) + interior])
    same_rms = float(np.sqrt(np.mean(same_inner**2)))
    high_sets = [i for i, (index, _, _) in enumerate(sets) if index == 0]

    def rms_vs_truth(phase_map, n=0):  # interior rms of (phase + 2*pi*n/12 - phi_true) of the high sequence
        error = _circular_difference(np.asarray(phase_map, dtype=np.float64) + TWO_PI * n / steps, phi_high)
        return float(np.sqrt(np.mean(error[interior] ** 2)))

    return {
        "frames": 2 * steps,
        "steps": steps,
        "frequencies": [F_HIGH, F_LOW["mw"]],
        "ours_24_frames": ours_24,
        "opencv_24_frames": opencv_24,
        "opencv_per_set_ms": opencv_24["best_ms"] / len(sets),
        "ours_3_frame_sets": ours_sets,
        "ratio_24_frames": _ratio(opencv_24, ours_24),
        "ratio_3_frame_sets": _ratio(opencv_24, ours_sets),
        "peak_memory_mib": {"ours_24_frames": peak_memory_mib(lambda: [wrapped_phase(s) for s in sequences])},
        "opencv": f"cv2 {cv2.__version__} structured_light.SinusoidalPattern PSP computePhaseMap "
                  f"({cv2.getNumThreads()} threads)",
        "how_scaled": f"OpenCV's PSP takes 3 frames per call: the 24 frames are {len(sets)} disjoint 3-frame "
                      f"sets (frames n, n+8, n+4 of each 12-step sequence, n = 0..3; shift +2pi/3 per "
                      f"frame); its 24-frame time is the measured total of the {len(sets)} calls "
                      f"= {len(sets)} x time per set. Ours does the 24 frames as 2 calls of 12 frames, and "
                      f"is also timed on the same {len(sets)} sets (ratio_3_frame_sets).",
        "agreement": {
            "border_px_excluded": border,
            "same_sets_rms_rad": same_rms,
            "same_sets_p99_rad": float(np.percentile(same_inner, 99)),
            "same_sets_max_rad": float(same_inner.max()),
            "vs_12_step_rms_rad": float(np.sqrt(np.mean(vs_inner**2))),
            "vs_12_step_max_rad": float(vs_inner.max()),
            "rms_vs_truth_rad": {
                "ours_12_step": rms_vs_truth(ours_maps[0].phase),
                "ours_3_frame_sets": float(np.mean([rms_vs_truth(ours_set_maps[i], sets[i][1]) for i in high_sets])),
                "opencv_3_frame_sets": float(np.mean([rms_vs_truth(opencv_maps[i], sets[i][1]) for i in high_sets])),
            },
            "bound_rms_rad": PHASE_SAME_SETS_RMS_BOUND_RAD,
            "agree": bool(same_rms < PHASE_SAME_SETS_RMS_BOUND_RAD),
            "note": "OpenCV's phase of set n equals phi - 2*pi*n/12 (shift_sign +1, no offset), the "
                    "quantity ours computes with shift_sign=+1; OpenCV band-pass filters each frame "
                    "(DFT, DC removed, 42x42 window around the fringe peak) before the 3-step formula, "
                    "so the two differ by that filter, not by convention.",
        },
    }


def bench_unwrap(phases, scene, repeats) -> dict:
    """MF / MW / NT unwrapping: ``dptpu.fpp.tpu`` against the bare equations."""
    extent = float(PROJECTOR_SIZE[0])
    phi_true = TWO_PI * F_HIGH * scene["projector_x"] / extent  # (H, W)
    psi_h = phases[F_HIGH]
    methods = {
        "mf": (lambda: unwrap_mf(psi_h, phases[F_LOW["mf"]], F_HIGH, F_LOW["mf"]),
               lambda: reference_mf(psi_h, phases[F_LOW["mf"]], F_HIGH, F_LOW["mf"]),
               "np.round((f_h*psi_l - f_l*psi_h) / (2*pi*f_l)), Eq. (5)"),
        "mw": (lambda: unwrap_mw(psi_h, phases[F_LOW["mw"]], F_HIGH, F_LOW["mw"]),
               lambda: reference_mw(psi_h, phases[F_LOW["mw"]], F_HIGH, F_LOW["mw"]),
               "psi_eq = np.mod(psi_h - psi_l, 2*pi); np.round((f_h*psi_eq - f_eq*psi_h) / (2*pi*f_eq)), "
               "Eqs. (6)-(7)"),
        "nt": (lambda: unwrap_nt(psi_h, phases[F_LOW["nt"]], F_HIGH, F_LOW["nt"], extent),
               lambda: reference_nt(psi_h, phases[F_LOW["nt"]], F_HIGH, F_LOW["nt"], extent),
               "argmin over the reachable (k_h, k_l) pairs of |x_p(psi_h, k_h) - x_p(psi_l, k_l)|, "
               f"{reference_nt_pairs(F_HIGH, F_LOW['nt'], extent)[0].size} pairs, vectorized in blocks of rows"),
    }
    report = {}
    for name, (ours_call, reference_call, reference_text) in methods.items():
        ours, result = time_call(ours_call, repeats)
        reference, (k_ref, _) = time_call(reference_call, repeats)
        valid = result.valid
        differ = int(np.count_nonzero(valid & (result.fringe_order != k_ref)))
        correct = np.abs(np.where(valid, result.absolute_phase, np.inf) - phi_true) < np.pi
        report[name] = {
            "f_h": F_HIGH,
            "f_l": F_LOW[name],
            "ours": ours,
            "reference": reference,
            "ratio": _ratio(reference, ours),
            "peak_memory_mib": {"ours": peak_memory_mib(ours_call), "reference": peak_memory_mib(reference_call)},
            "reference_is": reference_text,
            "orders_differ": differ,
            "ours_invalid": int(np.count_nonzero(~valid)),
            "correct_fraction": float(np.count_nonzero(correct) / correct.size),
            "agree": differ == 0,
        }
    return report


def bench_triangulate(rig, coord, scene, repeats, subset_pixels, rng) -> dict:
    """Whole-image triangulation: ``Triangulator`` against the per-pixel 3x3 solve on a subset."""
    height, width = coord.shape
    total = height * width
    count = min(subset_pixels, total)
    flat = np.sort(rng.choice(total, size=count, replace=False))
    rows, cols = np.unravel_index(flat, coord.shape)
    pixels = np.stack([cols, rows], axis=-1).astype(np.float64)  # (M, 2) as (u, v)
    coord_subset = coord[rows, cols]

    precompute, triangulator = time_call(lambda: Triangulator(rig), repeats)
    ours, points = time_call(lambda: triangulator.points(coord), repeats)
    reference_subset, points_ref = time_call(lambda: triangulate_reference(rig, pixels, coord_subset), repeats)
    scale = total / count
    reference_full = {key: value * scale for key, value in reference_subset.items()}
    difference = float(np.max(np.abs(points[rows, cols] - points_ref)))
    error = np.linalg.norm(points - scene["points"], axis=-1)
    return {
        "pixels": total,
        "subset_pixels": count,
        "precompute": precompute,
        "ours": ours,
        "reference_subset": reference_subset,
        "reference_full_scaled": reference_full,
        "how_scaled": f"triangulate_reference (one 3x3 np.linalg.solve per pixel and projector iteration) is "
                      f"timed on {count} random pixels and multiplied by {total}/{count} = {scale:.2f}",
        "ratio": _ratio(reference_full, ours),
        "ratio_with_precompute": reference_full["best_ms"] / (ours["best_ms"] + precompute["best_ms"]),
        "peak_memory_mib": {"ours_points": peak_memory_mib(lambda: triangulator.points(coord)),
                            "ours_precompute": peak_memory_mib(lambda: Triangulator(rig))},
        "max_difference_mm": difference,
        "rms_error_vs_scene_mm": float(np.sqrt(np.mean(error**2))),
        "bound_mm": TRIANGULATION_BOUND_MM,
        "agree": bool(difference < TRIANGULATION_BOUND_MM),
    }


def bench_node_paths(images_high, images_low, size, repeats) -> dict:
    """The nodes' hot paths per scan: phase (24 frames), unwrap (MW), cloud (real-like distortion)."""
    stacks = [images_high, images_low]

    def phase_before():
        return [reference_phase_node(stack, NODE_MIN_MODULATION_DN, NODE_SATURATION_DN) for stack in stacks]

    def phase_as_called():  # dptpu.fpp.scan_phase.scan_phase_maps today: float64 maps, cast by the node
        maps_list = []
        for stack in stacks:
            maps = wrapped_phase(stack, shift_sign=-1, phase_offset=0.0)
            valid = quality_mask(stack, maps.modulation, min_modulation=NODE_MIN_MODULATION_DN)
            phase32 = maps.phase.astype(np.float32)
            maps_list.append((np.where(phase32 >= TWO_PI, np.float32(0.0), phase32),
                              maps.modulation.astype(np.float32), valid))
        return maps_list

    def phase_float32():  # the same with wrapped_phase(..., dtype=np.float32): no casts
        maps_list = []
        for stack in stacks:
            maps = wrapped_phase(stack, shift_sign=-1, phase_offset=0.0, dtype=np.float32)
            maps_list.append((maps.phase, maps.modulation,
                              quality_mask(stack, maps.modulation, min_modulation=NODE_MIN_MODULATION_DN)))
        return maps_list

    before, reference = time_call(phase_before, repeats, cpu=True)
    as_called, ours = time_call(phase_as_called, repeats, cpu=True)
    float32, ours32 = time_call(phase_float32, repeats, cpu=True)
    phase_difference = max(float(np.abs(_circular_difference(mine[0].astype(np.float64),
                                                              ref[0].astype(np.float64))).max())
                           for result in (ours, ours32) for mine, ref in zip(result, reference))
    modulation_difference = max(float(np.max(np.abs(mine[1] / ref[1] - 1.0)))
                                for result in (ours, ours32) for mine, ref in zip(result, reference))
    mask_differ = sum(int(np.count_nonzero(mine[2] != ref[2]))
                      for result in (ours, ours32) for mine, ref in zip(result, reference))
    phase = {
        "frames": sum(len(stack) for stack in stacks),
        "before": before, "ours_as_called": as_called, "ours_float32": float32,
        "ratio_as_called": _ratio(before, as_called), "ratio_float32": _ratio(before, float32),
        "max_phase_difference_rad": phase_difference,
        "max_modulation_relative_difference": modulation_difference,
        "mask_pixels_differ": mask_differ,
        "bound_rad": NODE_PHASE_BOUND_RAD,
        "same": bool(phase_difference < NODE_PHASE_BOUND_RAD and modulation_difference < 1e-5 and mask_differ == 0),
    }

    valid = ours32[0][2] & ours32[1][2]
    unwrap_timing, unwrapped = time_call(
        lambda: unwrap("mw", ours32[0][0], ours32[1][0], F_HIGH, F_LOW["mw"], valid=valid), repeats, cpu=True)
    k_reference, _ = reference_mw(ours32[0][0].astype(np.float64), ours32[1][0].astype(np.float64),
                                  F_HIGH, F_LOW["mw"])
    orders_differ = int(np.count_nonzero(unwrapped.valid & (unwrapped.fringe_order != k_reference)))
    unwrap_report = {"ours_as_called": unwrap_timing, "orders_differ_from_bare_equation": orders_differ,
                     "same": orders_differ == 0}

    rig = make_rig(size, camera_dist=REAL_LIKE_CAMERA_DIST, projector_dist=REAL_LIKE_PROJECTOR_DIST)
    scene = make_scene(rig)
    coord = scene["projector_x"]  # (H, W) measured projector column, noise free
    precompute, triangulator = time_call(lambda: Triangulator(rig), max(1, min(repeats, 3)), cpu=True)
    tri_before, metres_before = time_call(
        lambda: cloud_node_metres(rig, reference_points_fixed_point(rig, triangulator.rays, coord)), repeats, cpu=True)
    tri_points, world = time_call(lambda: triangulator.points(coord), repeats, cpu=True)
    tri_as_called, metres = time_call(lambda: cloud_node_metres(rig, triangulator.points(coord)), repeats, cpu=True)
    tri_camera, metres_direct = time_call(lambda: triangulator.camera_points(coord, scale=rig.scale_to_m),
                                          repeats, cpu=True)
    converged = reference_points_fixed_point(rig, triangulator.rays, coord, iterations=50)
    fixed_six = reference_points_fixed_point(rig, triangulator.rays, coord)
    difference = float(np.nanmax(np.abs(world - converged)))
    with np.errstate(invalid="ignore", divide="ignore"):
        relative = float(np.nanmax(np.abs(metres_direct - metres) / np.linalg.norm(metres, axis=-1, keepdims=True)))
    error = np.linalg.norm(world - scene["points"], axis=-1)
    triangulate = {
        "projector_dist": list(REAL_LIKE_PROJECTOR_DIST), "camera_dist": list(REAL_LIKE_CAMERA_DIST),
        "precompute": precompute, "before": tri_before, "ours_points": tri_points,
        "ours_as_called": tri_as_called, "ours_camera_points": tri_camera,
        "ratio_as_called": _ratio(tri_before, tri_as_called), "ratio_camera_points": _ratio(tri_before, tri_camera),
        "max_difference_vs_converged_fixed_point_mm": difference,
        "max_difference_vs_6_iterations_mm": float(np.nanmax(np.abs(world - fixed_six))),
        "max_error_vs_scene_mm": float(np.nanmax(error)),
        "camera_points_max_relative_difference": relative,
        "bound_mm": NODE_POINTS_BOUND_MM,
        "same": bool(difference < NODE_POINTS_BOUND_MM and relative < NODE_METRES_RELATIVE_BOUND),
    }
    per_scan = {key: phase[p_key]["best_ms"] + unwrap_timing["best_ms"] + triangulate[t_key]["best_ms"]
                for key, p_key, t_key in (("before", "before", "before"),
                                          ("ours_as_called", "ours_as_called", "ours_as_called"),
                                          ("ours_if_nodes_adopt", "ours_float32", "ours_camera_points"))}
    return {"phase": phase, "unwrap_mw": unwrap_report, "triangulate": triangulate, "per_scan_best_ms": per_scan,
            "note": "before = the previous implementations written out in this file; as_called = what the phase "
                    "and cloud nodes call today; float32 / camera_points = wrapped_phase(dtype=np.float32) and "
                    "Triangulator.camera_points, which the nodes can adopt; per_scan sums the three nodes' "
                    "best times (unwrap as called in all three)."}


def machine() -> dict:
    """Processor, cores and library versions of this run."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import cv2

    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
    }


def run_benchmarks(*, size=CAMERA_SIZE, repeats=DEFAULT_REPEATS, subset_pixels=DEFAULT_SUBSET_PIXELS,
                   seed=0) -> dict:
    """All three benchmarks on one seeded synthetic scene.

    Parameters
    ----------
    size : (int, int)
        Camera ``(width, height)`` in pixels; at least 96x64 (OpenCV's band-pass window needs it).
    repeats : int
        Timed runs per measurement, >= 1.
    subset_pixels : int
        Pixels on which the per-pixel reference triangulation is timed, >= 1.
    seed : int
        Seed of ``np.random.default_rng`` for noise and the pixel subset.

    Returns
    -------
    dict
        ``{"machine", "size", "repeats", "phase", "unwrap", "triangulate", "node_paths"}`` (see the module
        docstring);
        times in ms, ratios = reference / ours.
    """
    width, height = _check_size(size)
    if isinstance(repeats, bool) or not isinstance(repeats, (int, np.integer)) or repeats < 1:
        raise ValueError(f"repeats must be an integer >= 1; got {repeats!r}")
    if isinstance(subset_pixels, bool) or not isinstance(subset_pixels, (int, np.integer)) or subset_pixels < 1:
        raise ValueError(f"subset_pixels must be an integer >= 1; got {subset_pixels!r}")
    rng = np.random.default_rng(seed)
    rig = make_rig((width, height))
    scene = make_scene(rig)
    frequencies = [F_HIGH, *F_LOW.values()]
    images = {f: fringe_images(scene, f, STEPS, rng) for f in frequencies}
    phases = {f: wrapped_phase(images[f]).phase for f in frequencies}

    phi_high = TWO_PI * F_HIGH * scene["projector_x"] / PROJECTOR_SIZE[0]  # (H, W) true absolute phase
    phase = bench_phase(images[F_HIGH], images[F_LOW["mw"]], phi_high, repeats)
    unwrap = bench_unwrap(phases, scene, repeats)
    absolute = unwrap_mf(phases[F_HIGH], phases[F_LOW["mf"]], F_HIGH, F_LOW["mf"]).absolute_phase
    coord = projector_coordinate(absolute, F_HIGH, PROJECTOR_SIZE[0])  # (H, W) projector column
    triangulate = bench_triangulate(rig, coord, scene, repeats, subset_pixels, rng)
    node_paths = bench_node_paths(images[F_HIGH], images[F_LOW["mw"]], (width, height), repeats)
    return {
        "machine": machine(),
        "size": [width, height],
        "repeats": repeats,
        "timing": "wall clock (time.perf_counter), best and median of the repeats, ms; "
                  "ratio = reference / ours from the best times",
        "phase": phase,
        "unwrap": unwrap,
        "triangulate": triangulate,
        "node_paths": node_paths,
    }


MIN_SIZE = (96, 64)


def parse_size(text) -> tuple[int, int]:
    """``"640x480"`` -> ``(640, 480)``; ValueError naming the expected form otherwise."""
    parts = str(text).lower().split("x")
    if len(parts) != 2 or not all(part.strip().isdigit() for part in parts):
        raise ValueError(f"size must be WIDTHxHEIGHT in pixels, e.g. 640x480; got {text!r}")
    return _check_size((int(parts[0]), int(parts[1])))


def _check_size(size) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in size)
    except (TypeError, ValueError):
        raise ValueError(f"size must be (width, height) in pixels; got {size!r}") from None
    if width < MIN_SIZE[0] or height < MIN_SIZE[1]:
        raise ValueError(
            f"size must be at least {MIN_SIZE[0]}x{MIN_SIZE[1]} pixels (OpenCV's PSP band-pass window needs "
            f"it); got {width}x{height}"
        )
    return width, height


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


def _ms(timing: dict) -> str:
    return f"{timing['best_ms']:10.2f} {timing['median_ms']:10.2f}"


def format_report(report: dict) -> str:
    """The report as a readable text table."""
    m = report["machine"]
    width, height = report["size"]
    lines = [
        f"dptpu bench fpp: {width}x{height} camera, best/median of {report['repeats']} runs, ms "
        f"(ratio = reference / ours, best times; > 1: ours faster)",
        f"machine: {m['cpu']}, {m['cores']} cores; Python {m['python']}, numpy {m['numpy']}, OpenCV {m['opencv']}",
        "",
        f"{'measurement':44s} {'best ms':>10s} {'median ms':>10s} {'ratio':>8s}",
    ]

    def row(name, timing, ratio=None):
        ratio_text = f"{ratio:8.2f}" if ratio is not None else ""
        lines.append(f"{name:44s} {_ms(timing)} {ratio_text}")

    p = report["phase"]
    f_high, f_low = p["frequencies"]
    lines.append(f"(a) wrapped phase, 24 frames = 2 x 12 steps, f = {f_high:g} and {f_low:g}")
    row("  ours wrapped_phase, 2 x 12 frames", p["ours_24_frames"])
    row("  OpenCV PSP computePhaseMap, 8 sets x 3", p["opencv_24_frames"], p["ratio_24_frames"])
    row("  ours wrapped_phase, same 8 sets x 3", p["ours_3_frame_sets"])
    lines.append(f"{'  like for like (OpenCV / ours on 3-frame sets)':66s} {p['ratio_3_frame_sets']:8.2f}")
    a = p["agreement"]
    lines.append(f"  OpenCV per 3-frame set: {p['opencv_per_set_ms']:.2f} ms (see note 1)")
    lines.append(
        f"  agreement, interior ({a['border_px_excluded']} px border excluded): OpenCV vs ours on the same sets rms "
        f"{a['same_sets_rms_rad']:.4f} rad (p99 {a['same_sets_p99_rad']:.4f}, max {a['same_sets_max_rad']:.4f}) "
        f"-> {'AGREE' if a['agree'] else 'DISAGREE'} (rms < {a['bound_rms_rad']})"
    )
    truth = a["rms_vs_truth_rad"]
    lines.append(
        f"  rms error vs the true phase (f = {f_high:g}, interior): ours 12-step {truth['ours_12_step']:.4f},"
        f" ours 3-frame {truth['ours_3_frame_sets']:.4f}, OpenCV PSP 3-frame {truth['opencv_3_frame_sets']:.4f} rad"
    )
    lines.append("(b) temporal phase unwrapping, ours vs the bare equation in numpy")
    for name, u in report["unwrap"].items():
        row(f"  ours unwrap_{name} ({u['f_h']:g} / {u['f_l']:g})", u["ours"])
        row(f"  reference {name}", u["reference"], u["ratio"])
        lines.append(
            f"    orders differ: {u['orders_differ']} px -> {'AGREE' if u['agree'] else 'DISAGREE'}; invalid (ours): "
            f"{u['ours_invalid']}; correct vs scene: {100 * u['correct_fraction']:.2f} %"
        )
    t = report["triangulate"]
    lines.append(f"(c) triangulation of {t['pixels']} pixels")
    row("  ours Triangulator(rig) (precompute)", t["precompute"])
    row("  ours Triangulator.points(coord)", t["ours"])
    row(f"  triangulate_reference, {t['subset_pixels']} px", t["reference_subset"])
    row("  triangulate_reference, scaled to image", t["reference_full_scaled"], t["ratio"])
    lines.append(f"{'  ratio counting the precompute too':66s} {t['ratio_with_precompute']:8.2f}")
    lines.append(
        f"    max |ours - reference| {t['max_difference_mm']:.2e} mm -> {'AGREE' if t['agree'] else 'DISAGREE'} "
        f"(< {t['bound_mm']:g} mm); rms error vs scene {t['rms_error_vs_scene_mm']:.4f} mm"
    )
    n = report["node_paths"]
    lines.append("(d) node hot paths per scan (best / median wall ms, best process CPU ms; ratio = before / ours)")

    def node_row(name, timing, ratio=None):
        ratio_text = f"{ratio:8.2f}" if ratio is not None else ""
        lines.append(f"{name:44s} {_ms(timing)} {ratio_text}   cpu {timing['best_cpu_ms']:.2f}")

    np_, nu, nt = n["phase"], n["unwrap_mw"], n["triangulate"]
    node_row(f"  phase node, {np_['frames']} frames: before", np_["before"])
    node_row("  ours as the node calls it (float64 maps)", np_["ours_as_called"], np_["ratio_as_called"])
    node_row("  ours with dtype=float32", np_["ours_float32"], np_["ratio_float32"])
    lines.append(f"    max |phase - before| {np_['max_phase_difference_rad']:.1e} rad (< {np_['bound_rad']:g}), "
                 f"modulation {np_['max_modulation_relative_difference']:.1e} relative, mask pixels differ "
                 f"{np_['mask_pixels_differ']} -> same: {'yes' if np_['same'] else 'NO'}")
    node_row("  unwrap node, MW on float32 phases + mask", nu["ours_as_called"])
    lines.append(f"    orders differ from the bare equation: {nu['orders_differ_from_bare_equation']} "
                 f"-> same: {'yes' if nu['same'] else 'NO'}")
    node_row("  cloud node, real-like distortion: precompute", nt["precompute"])
    node_row(f"  before: fixed point x{FIXED_POINT_ITERATIONS} + camera metres", nt["before"])
    node_row("  ours points() alone", nt["ours_points"])
    node_row("  ours points() + camera metres (as called)", nt["ours_as_called"], nt["ratio_as_called"])
    node_row("  ours camera_points(coord, scale)", nt["ours_camera_points"], nt["ratio_camera_points"])
    lines.append(
        f"    max |ours - converged fixed point| {nt['max_difference_vs_converged_fixed_point_mm']:.1e} mm "
        f"(< {nt['bound_mm']:g}; vs 6 iterations {nt['max_difference_vs_6_iterations_mm']:.1e}), vs scene max "
        f"{nt['max_error_vs_scene_mm']:.1e} mm; camera_points vs as called "
        f"{nt['camera_points_max_relative_difference']:.1e} relative -> same: {'yes' if nt['same'] else 'NO'}")
    per_scan = n["per_scan_best_ms"]
    lines.append(f"  per scan (phase + unwrap + cloud, best): before {per_scan['before']:.1f} ms, as called "
                 f"{per_scan['ours_as_called']:.1f} ms, if the nodes adopt float32 / camera_points "
                 f"{per_scan['ours_if_nodes_adopt']:.1f} ms")
    memory = [f"phase {p['peak_memory_mib']['ours_24_frames']:.1f}",
              *(f"unwrap_{name} {u['peak_memory_mib']['ours']:.1f} (reference {u['peak_memory_mib']['reference']:.1f})"
                for name, u in report["unwrap"].items()),
              f"Triangulator {t['peak_memory_mib']['ours_precompute']:.1f}, "
              f"points {t['peak_memory_mib']['ours_points']:.1f}"]
    lines += [
        f"peak extra memory of ours, MiB (tracemalloc): {', '.join(memory)}",
        "",
        f"note 1: {p['how_scaled']}",
        f"note 2: {t['how_scaled']}.",
        f"note 3: {a['note']}",
        f"note 4: {n['note']}",
    ]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description="Benchmark dptpu.fpp against references (not a test).")
    add_arguments(parser)
    return parser


def add_arguments(parser) -> None:
    """The benchmark's options, shared by ``python benchmarks/fpp_bench.py`` and ``dptpu bench fpp``."""
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--repeats", type=int, default=DEFAULT_REPEATS,
                        help=f"timed runs per measurement (default {DEFAULT_REPEATS})")
    parser.add_argument("--size", default=f"{CAMERA_SIZE[0]}x{CAMERA_SIZE[1]}",
                        help="camera image size WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--subset", type=int, default=DEFAULT_SUBSET_PIXELS,
                        help=f"pixels for the per-pixel reference triangulation (default {DEFAULT_SUBSET_PIXELS})")


def run(args) -> int:
    """Run with parsed options; print the table or JSON. Returns 0, or 1 if a pair disagrees.

    ``args`` has ``json`` (bool), ``size`` (``"WxH"``), ``repeats`` and ``subset`` (int); ``None`` for
    ``size``, ``repeats`` or ``subset`` means the default.
    """
    size = parse_size(args.size) if getattr(args, "size", None) is not None else CAMERA_SIZE
    repeats = DEFAULT_REPEATS if getattr(args, "repeats", None) is None else args.repeats
    subset = DEFAULT_SUBSET_PIXELS if getattr(args, "subset", None) is None else args.subset
    report = run_benchmarks(size=size, repeats=repeats, subset_pixels=subset)
    if getattr(args, "json", False):
        print(json.dumps(report, indent=2))
    else:
        print(format_report(report))
    node_paths = report["node_paths"]
    agree = [report["phase"]["agreement"]["agree"], report["triangulate"]["agree"],
             *(u["agree"] for u in report["unwrap"].values()),
             node_paths["phase"]["same"], node_paths["unwrap_mw"]["same"], node_paths["triangulate"]["same"]]
    return 0 if all(agree) else 1


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return run(args)
    except ValueError as exc:
        print(f"fpp_bench: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
