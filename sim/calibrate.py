"""Calibration round trip in the twin: render checkerboard poses, calibrate, compare with the twin's true rig.

1. :func:`board_poses`: ``count`` poses of a checkerboard at the rig's working distance (0.93..1.07 of it), tilted
   20..40 degrees in directions spread all around, turned by up to 15 degrees about its normal, the whole board
   (and a thin white border) inside the camera image;
2. :func:`render_calibration_poses`: per pose one trace of :func:`dptpu.sim.scenes.board_scene` and the frames of a
   vertical (``fringe_axis: x``) and a horizontal (``fringe_axis: y``) fringe set plus a white frame, written as a
   calibration pose folder (``pose_XX/x``, ``pose_XX/y``: ``dptpu-capture/1``; docs/calibration.md). Each camera
   pixel integrates ``supersample`` x ``supersample`` rays (traced with the camera resized by ``supersample``, then
   binned): a real sensor integrates over its pixel area, and corner detection on one ray per pixel (jagged square
   edges) costs ~0.3 px of corner accuracy, i.e. ~1 % of focal length;
3. :func:`dptpu.fpp.rig_calibration.calibrate_from_folders` on those folders (exactly what ``dptpu calibrate`` runs
   on real captures);
4. :func:`compare_with_truth`: intrinsics, baseline and the projector's pose relative to the camera against the
   twin's rig.

The issue's bounds (docs/calibration.md): focal lengths within 0.5 %, baseline within 1 mm.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from dptpu.fpp.calibration import Rig
from dptpu.fpp.capture import PhaseFrames, write_capture
from dptpu.fpp.rig_calibration import Board, RigCalibration, calibrate_from_folders
from dptpu.fpp.stereo_calibration import project

from .image_formation import SequenceSpec, quantize, render_frames_float
from .raycast import trace
from .rig import resize_camera, working_distance
from .scenes import board_scene

__all__ = ["DEFAULT_BOARD", "board_poses", "render_calibration_poses", "compare_with_truth", "round_trip",
           "format_report"]

#: A board that nearly fills the DP-TPU camera's narrow (~14 degree) view at its working distance: 10x8 inner
#: corners, 13 mm squares (143 x 117 mm of squares).
DEFAULT_BOARD = Board(10, 8, 13.0)


def board_poses(rig: Rig, board: Board, count: int, *, seed: int = 0, max_tilt_deg: float = 40.0,
                border_squares: float = 1.3) -> list[tuple[np.ndarray, np.ndarray]]:
    """Board-to-world poses ``X_world = R @ X_board + T`` whose board lies inside the camera image.

    Parameters
    ----------
    rig : Rig
    board : Board
    count : int
        Number of poses (>= 3).
    seed : int
        Seed of the random draws.
    max_tilt_deg : float
        Largest tilt of the board's normal from the camera axis; tilts are drawn in ``[max/2, max]``, their
        directions spread evenly around the axis (Zhang's method needs views that are not parallel).
    border_squares : float
        Board margin that must be in view too, in squares beyond the outer inner corners (1 = the outer squares).

    Returns
    -------
    list of (R (3, 3), T (3,))
        ``T`` is the world position of the first inner corner (:func:`dptpu.sim.scenes.board_scene`).

    Raises
    ------
    ValueError
        When the board cannot be placed in view (too big for the camera's field of view).
    """
    if count < 3:
        raise ValueError(f"a calibration needs at least 3 board poses; got {count}")
    rng = np.random.default_rng(seed)
    camera = rig.camera
    distance = working_distance(rig)
    s = board.square_mm
    centre = np.array([(board.cols - 1) / 2 * s, (board.rows - 1) / 2 * s, 0.0])
    margin = border_squares * s
    right, bottom = (board.cols - 1) * s + margin, (board.rows - 1) * s + margin
    outline = np.array([[-margin, -margin, 0], [right, -margin, 0], [-margin, bottom, 0], [right, bottom, 0]])
    width, height = camera.size
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    for _ in range(200 * count):
        if len(poses) == count:
            break
        k = len(poses)
        tilt_rad = np.radians(max_tilt_deg) * rng.uniform(0.5, 1.0)
        direction = 2 * np.pi * k / count + rng.uniform(0.0, 0.3)
        tilt = Rotation.from_rotvec(tilt_rad * np.array([np.cos(direction), np.sin(direction), 0.0]))
        spin = Rotation.from_rotvec([0.0, 0.0, np.radians(rng.uniform(-15, 15))])
        R_board_camera = (tilt * spin).as_matrix()  # board -> camera
        offset = np.array([rng.uniform(-0.01, 0.01), rng.uniform(-0.008, 0.008), rng.uniform(0.93, 1.07)]) * distance
        T_board_camera = offset - R_board_camera @ centre
        pixels = project(camera, outline @ R_board_camera.T + T_board_camera)
        if pixels.min() >= 0 and pixels[:, 0].max() <= width - 1 and pixels[:, 1].max() <= height - 1:
            R = camera.R.T @ R_board_camera  # board -> world
            poses.append((R, camera.R.T @ (T_board_camera - camera.T)))
    if len(poses) < count:
        raise ValueError(f"board {board.cols}x{board.rows}:{board.square_mm:g} does not fit the camera's view "
                         f"{width}x{height} at {distance:.0f} {rig.units}; use a smaller board")
    return poses


def render_calibration_poses(rig: Rig, out_dir, *, board: Board = DEFAULT_BOARD, count: int = 10,
                             frequency: float = 16.0, steps: int = 4, supersample: int = 2, effects=None,
                             seed: int = 0, progress: bool = False) -> list[Path]:
    """Render ``count`` board poses in the twin as calibration pose folders ``out_dir/pose_XX/{x,y}``.

    Parameters
    ----------
    rig : Rig
        The twin's rig (its camera size is the capture size).
    out_dir : path-like
        Created; one ``pose_XX`` folder per pose.
    board : Board
    count : int
        Number of poses.
    frequency : float
        High frequency of both fringe directions (periods across the projector extent); each direction also gets
        ``f = 1`` so the absolute phase comes by multi-frequency unwrapping (Eq. (5)).
    steps : int
        Phase steps of every sequence.
    supersample : int
        Rays per pixel along each axis (module docstring).
    effects : list, optional
        Effects of image formation (default ``rig.effects``).
    seed : int
        Seed of the poses and of any noise.
    progress : bool
        A tqdm bar over the poses on stderr.

    Returns
    -------
    list of Path
        The pose folders.
    """
    if int(supersample) < 1:
        raise ValueError(f"supersample must be an integer >= 1; got {supersample!r}")
    s = int(supersample)
    out_dir = Path(out_dir)
    width, height = rig.camera.size
    fine = resize_camera(rig, (width * s, height * s)) if s > 1 else rig
    folders = []
    poses = board_poses(rig, board, count, seed=seed)
    for k, (R, T) in enumerate(tqdm(poses, desc="rendering poses", unit="pose", disable=not progress, file=sys.stderr)):
        scene = board_scene(fine, R, T, cols=board.cols, rows=board.rows, square_mm=board.square_mm)
        samples = trace(fine, scene)
        folder = out_dir / f"pose_{k:02d}"
        for axis in ("x", "y"):
            sequences = [SequenceSpec(frequency, steps, axis=axis), SequenceSpec(1.0, steps, axis=axis),
                         SequenceSpec(kind="white")]
            frames = render_frames_float(fine, samples, sequences, effects=effects, seed=seed * 1000 + 2 * k +
                                         (axis == "y"))
            binned = [quantize(f.reshape(len(f), height, s, width, s).mean(axis=(2, 4))) for f in frames]
            write_capture(folder / axis, sequences=[PhaseFrames(images=binned[0], frequency=frequency),
                                                    PhaseFrames(images=binned[1], frequency=1.0)],
                          projector_size=rig.projector.size, fringe_axis=axis, references={"white": binned[2][0]},
                          extras={"twin": {"board": f"{board.cols}x{board.rows}:{board.square_mm:g}",
                                           "pose_R": R.tolist(), "pose_T": T.tolist(), "supersample": s}})
        folders.append(folder)
    return folders


def compare_with_truth(result: RigCalibration, truth: Rig) -> dict[str, Any]:
    """Errors of a calibration against the twin's rig (world frames may differ: compared in the camera frame).

    Returns
    -------
    dict
        ``camera``/``projector``: ``fx``, ``fy``, ``cx``, ``cy`` true and estimated (pixels) and
        ``focal_error_percent`` (max of fx, fy); ``baseline_mm``: true, estimated, ``error_mm``;
        ``rotation_error_deg`` and ``translation_error_mm`` of the projector pose relative to the camera;
        ``rms_px`` of both devices (single-device Zhang fits) and of the joint fit.
    """
    report: dict[str, Any] = {}
    for name in ("camera", "projector"):
        true, estimated = getattr(truth, name), getattr(result.rig, name)
        entry: dict[str, Any] = {}
        for key, (i, j) in (("fx", (0, 0)), ("fy", (1, 1)), ("cx", (0, 2)), ("cy", (1, 2))):
            entry[key] = {"true": float(true.K[i, j]), "estimated": float(estimated.K[i, j])}
        entry["focal_error_percent"] = float(max(abs(entry[k]["estimated"] / entry[k]["true"] - 1) * 100
                                                 for k in ("fx", "fy")))
        entry["principal_point_error_px"] = float(np.hypot(entry["cx"]["estimated"] - entry["cx"]["true"],
                                                           entry["cy"]["estimated"] - entry["cy"]["true"]))
        entry["dist"] = {"true": true.dist.tolist(), "estimated": estimated.dist.tolist()}
        entry["rms_px"] = float(getattr(result, name).rms_px)
        report[name] = entry
    true_baseline = float(np.linalg.norm(truth.camera.center - truth.projector.center))
    report["baseline_mm"] = {"true": true_baseline, "estimated": result.baseline_mm,
                             "error_mm": abs(result.baseline_mm - true_baseline)}
    R_true = truth.projector.R @ truth.camera.R.T  # camera -> projector
    T_true = truth.projector.T - R_true @ truth.camera.T
    R_est = result.rig.projector.R @ result.rig.camera.R.T
    T_est = result.rig.projector.T - R_est @ result.rig.camera.T
    report["rotation_error_deg"] = float(np.degrees(np.linalg.norm(Rotation.from_matrix(R_est @ R_true.T).as_rotvec())))
    report["translation_error_mm"] = float(np.linalg.norm(T_est - T_true))
    report["joint_rms_px"] = {"camera": result.relative.rms_camera_px, "projector": result.relative.rms_projector_px}
    report["poses"] = len(result.names)
    return report


def round_trip(rig: Rig, out_dir, *, board: Board = DEFAULT_BOARD, count: int = 10, frequency: float = 16.0,
               steps: int = 4, supersample: int = 2, effects=None, seed: int = 0,
               progress: bool = False) -> tuple[RigCalibration, dict]:
    """Render ``count`` poses (:func:`render_calibration_poses`), calibrate them, compare with ``rig``
    (``progress``: tqdm bars on stderr).

    Returns
    -------
    (RigCalibration, dict)
        The calibration and :func:`compare_with_truth`'s report.
    """
    folders = render_calibration_poses(rig, out_dir, board=board, count=count, frequency=frequency, steps=steps,
                                       supersample=supersample, effects=effects, seed=seed, progress=progress)
    result = calibrate_from_folders(folders, board, progress=progress)
    return result, compare_with_truth(result, rig)


def format_report(report: dict) -> str:
    """The round-trip report as a few lines of text."""
    lines = []
    for name in ("camera", "projector"):
        e = report[name]
        lines.append(f"{name}: fx {e['fx']['estimated']:.2f} (true {e['fx']['true']:.2f}), "
                     f"fy {e['fy']['estimated']:.2f} (true {e['fy']['true']:.2f}), "
                     f"focal error {e['focal_error_percent']:.3f} %, "
                     f"principal point error {e['principal_point_error_px']:.2f} px")
    b = report["baseline_mm"]
    lines.append(f"baseline: {b['estimated']:.3f} mm (true {b['true']:.3f}), error {b['error_mm']:.3f} mm; "
                 f"relative pose error {report['rotation_error_deg']:.4f} deg, {report['translation_error_mm']:.3f} mm")
    return "\n".join(lines)
