"""``dptpu calibrate``: a rig file from checkerboard calibration poses (real captures or the twin's).

    dptpu calibrate POSE_DIRS... --board COLSxROWS:SQUARE_MM --out rig.yaml
    dptpu calibrate --twin --rig RIG [--poses N] [--size WIDTHxHEIGHT] --board ... --out rig.yaml [--keep DIR]

A pose folder holds the captures ``x/`` and ``y/`` (docs/calibration.md); a folder of pose folders stands for all
of them. With ``--twin`` the poses are rendered in the twin of ``--rig RIG`` first and the result is compared with it
(the round trip of :mod:`dptpu.sim.calibrate`). Shows progress bars (tqdm, stderr; ``--quiet``: none), prints the
reprojection error of each device (overall and per pose), writes a ``dptpu-rig/1`` file (world = camera frame, mm)
and ends with a one-line summary.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "calibrate", help="calibrate camera + projector from checkerboard poses -> dptpu-rig/1",
        description="Zhang's method for the camera, the projector as an inverse camera from the absolute phase of "
                    "vertical and horizontal fringes at the board corners, then the pair (docs/calibration.md).")
    parser.add_argument("pose_dirs", nargs="*", metavar="POSE_DIR",
                        help="calibration pose folders (each with x/ and y/ dptpu-capture/1 folders), or folders "
                             "of them")
    parser.add_argument("--board", required=True,
                        help="COLSxROWS:SQUARE_MM: inner corners and square edge, e.g. 10x8:13")
    parser.add_argument("--out", required=True, help="rig file to write (dptpu-rig/1 YAML)")
    parser.add_argument("--window", type=int, default=6,
                        help="half-size in camera pixels of the local homography around each corner (default 6)")
    twin = parser.add_argument_group("twin round trip (instead of POSE_DIRs)")
    twin.add_argument("--twin", action="store_true",
                      help="render the poses in the twin of --rig and compare the result with it")
    twin.add_argument("--rig", metavar="RIG", help="the twin's rig: dptpu-rig/1 or OpenCV file, 'CAM.mat,PRJ.mat' "
                                                   "(Bouguet) or 'nominal'")
    twin.add_argument("--poses", type=int, default=10, help="board poses to render (default 10)")
    twin.add_argument("--size", default=None, help="camera size WIDTHxHEIGHT for the render (default: the rig's)")
    twin.add_argument("--frequency", type=float, default=16.0, help="fringe frequency of both directions (default 16)")
    twin.add_argument("--supersample", type=int, default=2, help="rays per pixel along each axis (default 2)")
    twin.add_argument("--seed", type=int, default=0, help="seed of the board poses (default 0)")
    twin.add_argument("--keep", metavar="DIR",
                      help="write the rendered pose folders here (default: a temporary folder, deleted at the end)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(func=run)


def run(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.fpp.calibration import save_rig
    from dptpu.fpp.rig_calibration import calibrate_from_folders, parse_board

    board = parse_board(args.board)
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
