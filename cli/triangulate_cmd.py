"""``dptpu triangulate``: point cloud (PLY) of a calibrated capture folder.

    dptpu triangulate --capture DIR --method heterodyne [--model PATH|none] [--min-confidence C] [--units mm]
        --out cloud.ply

Unwraps like ``dptpu unwrap`` (the same code path, :func:`dptpu.cli.unwrap_cmd.unwrap_from_args`: the DP-TPU network
by default where it serves, ``--min-confidence``), turns the absolute phase into the projector coordinate
``x_p = phi * W_p / (2 pi f)``, intersects each valid camera ray with the projector plane of that
coordinate (:class:`dptpu.fpp.triangulate.Triangulator`, the capture's ``calibration`` rig file), drops the points
at depth edges (:func:`dptpu.fpp.depth_edges.edge_points`: flying points, the far side of a depth step, modulation
dips at depth edges, partly shadowed points predicted more than 1 mm off, isolated points; off with
``--keep-edges``) and the islands of a wrong fringe order (:func:`dptpu.fpp.order_islands.order_islands`; off with
``--keep-islands``) and writes the rest with open3d, in the
rig's world frame, in metres as every point-cloud file of dptpu (``--units mm``: millimetres). The summary line
counts what was dropped and why.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dptpu.cli.conventions import add_cloud_units_option, stage_bar
from dptpu.cli.unwrap_cmd import add_unwrap_arguments, summary, unwrap_from_args
from dptpu.fpp.calibration import load_rig
from dptpu.fpp.capture import CAPTURE_FILE, read_capture
from dptpu.fpp.depth_edges import DEFAULT_MAX_EDGE_ERROR_MM, edge_points
from dptpu.fpp.flying_points import DEFAULT_MAX_SLOPE
from dptpu.fpp.order_islands import order_islands
from dptpu.fpp.point_cloud_file import write_point_cloud
from dptpu.fpp.shadow_border import depth_per_pixel
from dptpu.fpp.triangulate import Triangulator, camera_depth, projector_coordinate


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "triangulate", help="point cloud (PLY) of a calibrated capture folder",
        description="Unwrap a capture folder, triangulate every valid pixel with the capture's calibration "
                    "(its 'calibration' rig file, dptpu-rig/1; required) and write the points as a PLY. "
                    "Points are in the rig's world frame, in metres (--units mm: millimetres), whatever the "
                    "rig file's units.")
    add_unwrap_arguments(parser)
    parser.add_argument("--out", required=True, type=Path, metavar="cloud.ply",
                        help="output point cloud (PLY; open3d picks the format from the suffix)")
    add_cloud_units_option(parser)
    parser.add_argument("--no-distortion", action="store_true",
                        help="ignore the lens distortion of camera and projector (pinhole triangulation)")
    parser.add_argument("--keep-edges", action="store_true",
                        help="keep the points at depth edges (flying points between surfaces, points beside a depth "
                             "step, modulation dips, isolated points; docs/nodes.md 'Flying points')")
    parser.add_argument("--max-edge-slope", type=float, default=DEFAULT_MAX_SLOPE, metavar="S",
                        help="depth step between neighbours, in pixel footprints, above which a point standing "
                             "apart from both neighbours along a line is a flying point "
                             f"(default {DEFAULT_MAX_SLOPE:g})")
    parser.add_argument("--keep-islands", action="store_true",
                        help="keep the islands of a wrong fringe order (regions whole orders off from the surface "
                             "around them; docs/nodes.md 'Order islands')")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    capture = read_capture(args.capture)
    if capture.calibration is None:
        raise ValueError(f"{capture.root / CAPTURE_FILE}: no 'calibration' key; triangulate needs a rig file "
                         f"(dptpu-rig/1, e.g. 'calibration: calibration.yaml') next to the frames")
    rig = load_rig(capture.calibration)
    for device, expected in (("camera", capture.camera_size), ("projector", capture.projector_size)):
        actual = tuple(getattr(rig, device).size)
        if actual != tuple(expected):
            raise ValueError(f"{capture.calibration.name}: {device} size is {actual[0]}x{actual[1]} but "
                             f"the capture's {device}.size is {expected[0]}x{expected[1]}")
    if args.out.is_dir():
        raise ValueError(f"--out {args.out}: is a folder; expected the path of the point cloud file to write (.ply)")
    if not args.out.parent.is_dir():
        raise FileNotFoundError(f"{args.out.parent}: output folder does not exist")

    if not args.max_edge_slope > 0:
        raise ValueError(f"--max-edge-slope must be > 0; got {args.max_edge_slope:g}")

    with stage_bar("triangulate", quiet=args.quiet) as step:
        line = _triangulate(args, capture, rig, step)
        step("done")
    print(line)
    return 0


def _triangulate(args: argparse.Namespace, capture, rig, step) -> str:
    """Unwrap, triangulate, filter and write the cloud; the summary line."""
    unwrapping = unwrap_from_args(args, step)
    result = unwrapping.result
    step("triangulating")
    x_p = projector_coordinate(np.where(result.valid, result.absolute_phase, np.nan), result.frequency,
                               capture.fringe_extent_px)  # (H, W), NaN where invalid
    triangulator = Triangulator(rig, axis=capture.fringe_axis, distortion=not args.no_distortion)
    points = triangulator.points(x_p)  # (H, W, 3), rig units
    keep = np.all(np.isfinite(points), axis=-1)  # (H, W)
    edges_note = "depth edges kept"
    if not args.keep_edges:
        depth = np.where(keep, camera_depth(points, rig.camera), np.nan)  # (H, W) camera z
        focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])

        def depth_at(projector_x: np.ndarray, pixels: np.ndarray) -> np.ndarray:  # the few pixels asked for
            return camera_depth(triangulator.points(projector_x, pixels=pixels), rig.camera)

        def per_px(where: np.ndarray) -> np.ndarray:  # the second triangulation, where edge_points needs it
            return depth_per_pixel(x_p, depth_at, capture.fringe_axis, depth=depth, where=where)

        edges = edge_points(depth, focal_px, result.modulation, lit=result.valid, depth_per_px=per_px,
                            max_edge_error=DEFAULT_MAX_EDGE_ERROR_MM * 1e-3 / rig.scale_to_m,
                            axis=capture.fringe_axis, max_slope=args.max_edge_slope)
        counts = edges.counts(keep)
        keep &= ~edges.dropped
        edges_note = (f"{counts['total']} points at depth edges dropped ({counts['flying']} flying, "
                      f"{counts['beside_step']} beside a step, {counts['modulation_dip']} modulation dips, "
                      f"{counts['shadow_border']} partly shadowed, {counts['isolated']} isolated)")
    step("filtering depth edges and islands of a wrong order")
    islands_note = "islands of a wrong order kept"
    if not args.keep_islands:
        islands = order_islands(result.absolute_phase, result.modulation, result.valid).islands & keep
        keep &= ~islands
        islands_note = f"{int(np.count_nonzero(islands))} points on islands of a wrong order dropped"
    cloud_points = points[keep]  # (M, 3)
    if cloud_points.shape[0] == 0:
        raise ValueError(f"no valid pixel to triangulate in {capture.root} ({args.method}); nothing written")
    step(f"writing {args.out}")
    write_point_cloud(args.out, cloud_points, unit=rig.units, file_unit=args.units)
    return (f"{args.method}: {cloud_points.shape[0]} points ({args.units}); {summary(unwrapping)}; {edges_note}; "
            f"{islands_note} -> {args.out}")
