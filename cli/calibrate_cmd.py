"""``dptpu calibrate``: a rig file from checkerboard calibration poses (real captures or the twin's).

    dptpu calibrate POSE_DIRS... --board COLSxROWS:SQUARE_MM --out rig.yaml
    dptpu calibrate --twin --rig RIG [--poses N] [--size WIDTHxHEIGHT] --board ... --out rig.yaml [--keep DIR]
    dptpu calibrate hand-eye VIEWS.yaml --rig RIG --board COLSxROWS:SQUARE_MM --out mount.yaml
    dptpu calibrate response CAPTURE_DIR... [--rig RIG] [--steps 3,4] --out rig.yaml

A pose folder holds the captures ``x/`` and ``y/`` (docs/calibration.md); a folder of pose folders stands for all
of them. With ``--twin`` the poses are rendered in the twin of ``--rig RIG`` first and the result is compared with it
(the round trip of :mod:`dptpu.sim.calibrate`). Shows progress bars (tqdm, stderr; ``--quiet``: none), prints the
reprojection error of each device (overall and per pose), writes a ``dptpu-rig/1`` file (world = camera frame, mm)
and ends with a one-line summary.

``hand-eye``: where the scanner sits on a robot (eye-in-hand) or beside it (eye-to-hand), from a ``dptpu-hand-eye/1``
views file (the flange pose at each board capture; :mod:`dptpu.fpp.hand_eye_file`) and the camera model of the
scanner's ``--rig`` (:mod:`dptpu.fpp.hand_eye`); writes the cloud node's ``mount_frame`` and ``mount_transform`` as a
ROS 2 parameter file (its ``/tf_static``, docs/ros2.md).

``response``: the projector's phase response, from captures that hold a 12-step (or longer) phase sequence and,
of the same frequency, the N-step phases to calibrate (their own sequences, or every N dividing the reference's
steps taken from its frames; :mod:`dptpu.fpp.phase_response_calibration`); writes ``--rig`` (default: the first
capture's ``calibration``) with ``projector.phase_response`` to ``--out``. Every later phase computation with that
rig file removes the error of the step counts it holds (docs/calibration.md "The projector's phase response").
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from .conventions import stage_bar


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "calibrate", help="calibrate camera + projector from checkerboard poses -> dptpu-rig/1",
        description="Zhang's method for the camera, the projector as an inverse camera from the absolute phase of "
                    "vertical and horizontal fringes at the board corners, then the pair (docs/calibration.md).")
    parser.add_argument("pose_dirs", nargs="*", metavar="POSE_DIR",
                        help="calibration pose folders (each with x/ and y/ dptpu-capture/1 folders), or folders "
                             "of them; or 'hand-eye VIEWS.yaml' for a hand-eye calibration, or 'response "
                             "CAPTURE_DIR...' for the projector's phase response (below)")
    parser.add_argument("--board",
                        help="COLSxROWS:SQUARE_MM: inner corners and square edge, e.g. 10x8:13 (rig and hand-eye "
                             "calibrations)")
    parser.add_argument("--out", required=True,
                        help="rig file to write (dptpu-rig/1 YAML); with hand-eye: the mount file (ROS 2 parameters)")
    parser.add_argument("--window", type=int, default=6,
                        help="half-size in camera pixels of the local homography around each corner (default 6)")
    twin = parser.add_argument_group("twin round trip (instead of POSE_DIRs)")
    twin.add_argument("--twin", action="store_true",
                      help="render the poses in the twin of --rig and compare the result with it")
    twin.add_argument("--rig", metavar="RIG", help="the twin's rig: dptpu-rig/1 or OpenCV file, 'CAM.mat,PRJ.mat' "
                                                   "(Bouguet) or 'nominal'; with hand-eye: the scanner's rig file "
                                                   "(its camera's intrinsics and distortion); with response: the "
                                                   "rig file to extend (default: the first capture's calibration)")
    twin.add_argument("--poses", type=int, default=10, help="board poses to render (default 10)")
    twin.add_argument("--size", default=None, help="camera size WIDTHxHEIGHT for the render (default: the rig's)")
    twin.add_argument("--frequency", type=float, default=16.0, help="fringe frequency of both directions (default 16)")
    twin.add_argument("--supersample", type=int, default=2, help="rays per pixel along each axis (default 2)")
    twin.add_argument("--seed", type=int, default=0, help="seed of the board poses (default 0)")
    twin.add_argument("--keep", metavar="DIR",
                      help="write the rendered pose folders here (default: a temporary folder, deleted at the end)")
    hand_eye = parser.add_argument_group("hand-eye calibration (dptpu calibrate hand-eye VIEWS.yaml --rig RIG --board "
                                         "... --out mount.yaml)")
    hand_eye.add_argument("--camera-frame", default="",
                          help="also write the cloud's frame_id (the camera optical frame; default: leave it)")
    response = parser.add_argument_group("projector phase response (dptpu calibrate response CAPTURE_DIR... "
                                         "[--rig RIG] --out rig.yaml)")
    response.add_argument("--steps", metavar="N[,N...]",
                          help="step counts to calibrate (default: every one the captures provide beside a 12-step "
                               "sequence)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(func=run)


def run(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.fpp.calibration import save_rig
    from dptpu.fpp.rig_calibration import calibrate_from_folders, parse_board

    if args.pose_dirs and args.pose_dirs[0] == "response":
        return _run_response(args)
    if args.steps is not None:
        raise ValueError("--steps belongs to 'dptpu calibrate response'")
    if args.board is None:
        raise ValueError("--board COLSxROWS:SQUARE_MM is required (the checkerboard's inner corners and square edge)")
    board = parse_board(args.board)
    if args.pose_dirs and args.pose_dirs[0] == "hand-eye":
        return _run_hand_eye(args, board)
    if args.twin and args.rig is None and len(args.pose_dirs) == 1:  # the old spelling --twin RIG
        raise ValueError(f"--twin takes no value now: write --twin --rig {args.pose_dirs[0]} (one name for a rig "
                         f"file in every command)")
    if args.twin:
        if args.pose_dirs:
            raise ValueError("give either POSE_DIRs or --twin --rig RIG, not both")
        if args.rig is None:
            raise ValueError("--twin needs --rig RIG (the twin's rig file, 'CAM.mat,PRJ.mat' or 'nominal')")
        return _run_twin(args, board)
    if args.rig is not None:
        raise ValueError("--rig names the twin's rig: give it with --twin (real poses need no rig)")
    if not args.pose_dirs:
        raise ValueError("give calibration pose folders (POSE_DIR...) or --twin --rig RIG")
    result = calibrate_from_folders(args.pose_dirs, board, window_px=args.window, progress=not args.quiet)
    _print_errors(result)
    save_rig(result.rig, args.out)
    print(summary_line(result, args.out))
    return 0


def _run_twin(args, board) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.fpp.calibration import save_rig
    from dptpu.sim.calibrate import format_report, round_trip
    from dptpu.sim.rig import load_twin_rig

    rig = load_twin_rig(args.rig, size=args.size)
    width, height = rig.camera.size
    where = f" -> {args.keep}" if args.keep else " (in a temporary folder)"
    print(f"rendering {args.poses} board poses in the twin ({width}x{height}){where}", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="dptpu-calibrate-") as scratch:
        result, report = round_trip(rig, args.keep or scratch, board=board, count=args.poses,
                                    frequency=args.frequency, supersample=args.supersample, seed=args.seed,
                                    progress=not args.quiet)
    _print_errors(result, short_names=not args.keep)  # the temporary folder is gone: its path would mislead
    print(format_report(report))
    save_rig(result.rig, args.out)
    baseline = report["baseline_mm"]
    print(summary_line(result, args.out) + f"; against the twin: baseline error {baseline['error_mm']:.3f} mm, "
          f"focal error camera {report['camera']['focal_error_percent']:.2f} %, projector "
          f"{report['projector']['focal_error_percent']:.2f} %")
    return 0


def _run_hand_eye(args, board) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dataclasses import replace

    import numpy as np
    from scipy.spatial.transform import Rotation
    from tqdm import tqdm

    from dptpu.fpp.calibration import load_rig
    from dptpu.fpp.hand_eye import MIN_VIEWS, calibrate_hand_eye
    from dptpu.fpp.hand_eye_file import load_board_image, read_hand_eye_views, write_mount_file
    from dptpu.fpp.rig_calibration import find_board_corners

    if len(args.pose_dirs) != 2:
        raise ValueError(f"dptpu calibrate hand-eye takes one views file (dptpu-hand-eye/1); got "
                         f"{len(args.pose_dirs) - 1}: {' '.join(args.pose_dirs[1:]) or 'none'}")
    if args.twin:
        raise ValueError("--twin is a rig calibration's; hand-eye takes a views file and --rig")
    if not args.rig:
        raise ValueError("dptpu calibrate hand-eye needs --rig RIG (the scanner's rig file: the camera's model)")
    views = read_hand_eye_views(args.pose_dirs[1])
    camera = load_rig(args.rig).camera
    corners, used, skipped = [], [], []  # the board's corners in the views where it was found; why the others not
    for index, capture in enumerate(tqdm(views.captures, desc="finding the board", unit="view", disable=args.quiet,
                                         file=sys.stderr)):
        image = load_board_image(capture)
        if (image.shape[1], image.shape[0]) != tuple(camera.size):
            raise ValueError(f"{capture}: the image is {image.shape[1]}x{image.shape[0]}; the rig's camera is "
                             f"{camera.size[0]}x{camera.size[1]}")
        try:
            corners.append(find_board_corners(image, board, where=capture.name))
        except ValueError as exc:  # a view without the whole board (out of the image, glare): left out, said why
            skipped.append(str(exc))
            tqdm.write(f"skipped view {index} ({exc})", file=sys.stderr)
            continue
        used.append(index)
    if len(used) < MIN_VIEWS:
        raise ValueError(f"{views.path}: the board was found in {len(used)} of {len(views.captures)} views; "
                         f"hand-eye calibration needs at least {MIN_VIEWS} (skipped: {'; '.join(skipped)})")
    views = replace(views, captures=tuple(views.captures[i] for i in used),
                    flange_poses=tuple(views.flange_poses[i] for i in used))
    result = calibrate_hand_eye(views.flange_poses, corners, board, camera, setup=views.setup)
    write_mount_file(args.out, result, views, camera_frame=args.camera_frame)
    parent = views.flange_frame if views.setup == "eye-in-hand" else views.base_frame
    x_mm = result.mount[:3, 3] * 1e3
    rpy = Rotation.from_matrix(result.mount[:3, :3]).as_euler("xyz", degrees=True)
    print("initial values (reprojection RMS): " + ", ".join(
        f"{name} {rms:.3f} px" for name, rms in sorted(result.initial_rms_px.items(), key=lambda item: item[1])))
    for capture, rms in zip(views.captures, result.view_rms_px):
        print(f"  {capture.name}: {rms:.4f} px")
    print(f"camera optical frame in {parent}: x {x_mm[0]:.3f} mm, y {x_mm[1]:.3f} mm, z {x_mm[2]:.3f} mm; "
          f"roll {rpy[0]:.4f}, pitch {rpy[1]:.4f}, yaw {rpy[2]:.4f} deg (fixed axes x, y, z)")
    left_out = f" ({len(skipped)} skipped: no board)" if skipped else ""
    print(f"hand-eye ({views.setup}) from {len(corners)} views{left_out} -> {args.out}: reprojection RMS "
          f"{result.rms_px:.3f} px (worst view {float(np.max(result.view_rms_px)):.3f} px); mount_frame {parent}")
    return 0


def _run_response(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    import dataclasses

    from dptpu.fpp.calibration import load_rig, save_rig
    from dptpu.fpp.capture import read_capture
    from dptpu.fpp.phase_response_calibration import calibrate_phase_response

    folders = args.pose_dirs[1:]
    if not folders:
        raise ValueError("dptpu calibrate response needs capture folders (CAPTURE_DIR...) holding a 12-step phase "
                         "sequence and the N-step phases of the same scene")
    if args.twin or args.board is not None:
        raise ValueError("--twin and --board belong to the rig calibration; 'response' takes capture folders")
    steps = None
    if args.steps is not None:
        try:
            steps = [int(text) for text in args.steps.split(",")]
        except ValueError:
            raise ValueError(f"--steps must be step counts such as 3 or 3,4; got {args.steps!r}") from None
        if any(n < 3 for n in steps):
            raise ValueError(f"--steps must be step counts >= 3; got {args.steps!r}")
    captures = [read_capture(folder) for folder in folders]
    rig_path = args.rig or captures[0].calibration
    if rig_path is None:
        raise ValueError(f"{captures[0].root}: the capture names no 'calibration' rig file; give --rig RIG (the rig "
                         f"file to add the projector's response to)")
    rig = load_rig(rig_path)
    with stage_bar("calibrate response", quiet=args.quiet) as step:  # seconds a capture (many pairs of phases)
        calibration = calibrate_phase_response(captures, steps=steps, progress=step)
        step("done")
    for n, fit in calibration.fits.items():
        by_frequency = ", ".join(f"{f:g}: {a:.4f}" for f, a in fit.amplitude_by_frequency_rad.items())
        print(f"{n} steps: cos_rad {fit.error.cos_rad:+.5f}, sin_rad {fit.error.sin_rad:+.5f} (amplitude "
              f"{fit.error.amplitude_rad:.4f} rad; per frequency {by_frequency}); {n}-step minus reference RMS "
              f"{fit.rms_before_rad:.4f} -> {fit.rms_after_rad:.4f} rad over {fit.pixels} pixels of "
              f"{len(fit.pairs)} sequence pairs")
    save_rig(dataclasses.replace(rig, phase_response=calibration.response), args.out)
    print(f"projector phase response of {', '.join(map(str, calibration.response.steps))} steps from "
          f"{len(captures)} capture(s) -> {args.out} (rig {rig_path})")
    return 0


def summary_line(result, out) -> str:
    """``calibrated 10 poses -> rig.yaml: RMS camera 0.05 px, projector 0.08 px; baseline 152.3 mm``."""
    return (f"calibrated {len(result.names)} poses -> {out}: RMS camera {result.camera.rms_px:.3f} px, projector "
            f"{result.projector.rms_px:.3f} px; baseline {result.baseline_mm:.1f} mm")


def _print_errors(result, *, short_names: bool = False) -> None:
    print(f"reprojection RMS: camera {result.camera.rms_px:.4f} px, projector {result.projector.rms_px:.4f} px "
          f"(joint fit: camera {result.relative.rms_camera_px:.4f} px, projector "
          f"{result.relative.rms_projector_px:.4f} px), {len(result.names)} poses")
    for name, camera_rms, projector_rms in zip(result.names, result.camera.view_rms_px, result.projector.view_rms_px):
        name = Path(name).name if short_names else name
        print(f"  {name}: camera {camera_rms:.4f} px, projector {projector_rms:.4f} px")
