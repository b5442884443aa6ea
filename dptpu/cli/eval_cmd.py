"""``dptpu eval sphere``: the paper's Fig. 3 figures and the project's own reconstruction of the real sphere."""
from __future__ import annotations

import json

from .data_paths import shared_data_dir


def register(subparsers) -> None:
    parser = subparsers.add_parser("eval", help="evaluate against reference data")
    targets = parser.add_subparsers(dest="target", metavar="TARGET", required=True)
    sphere = targets.add_parser("sphere", help="the DP-TPU standard sphere (paper Fig. 3) on real data")
    sphere.add_argument("--data", help="dptpu-sphere folder (default: $DPTPU_DATA/dptpu-sphere or "
                                       "../shared/data/dptpu-sphere)")
    sphere.add_argument("--json", action="store_true", help="print the figures as JSON")
    sphere.set_defaults(func=run_sphere)


def run_sphere(args) -> int:
    from dptpu.fpp import real_sphere

    data_dir = args.data or shared_data_dir() / "dptpu-sphere"
    report = real_sphere.evaluate(data_dir)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"DP-TPU standard sphere, diameter {real_sphere.SPHERE_DIAMETER_MM} mm, data: {data_dir}")
    print("Paper's method (pinhole, x_p - 1, algebraic fit), RMS of the sphere fit in um:")
    print(f"  {'calibration':12s}{'phase':8s}{'computed':>10s}{'Fig. 3 label':>14s}")
    for calibration, phase in real_sphere.COMBINATIONS:
        key = real_sphere.combination_key(calibration, phase)
        print(f"  {calibration:12s}{phase:8s}{report['paper'][key]:10.3f}{report['paper_figures_um'][key]:14.3f}")
    print("Own reconstruction (pose refined over all views, 0-based, camera + projector distortion, geometric fit):")
    print(f"  {'calibration':12s}{'phase':8s}{'RMS um':>9s}{'radius mm':>11s}{'points':>8s}"
          f"   edge band removed ({report['ours']['calib_real_phase_real']['edge_band_removed']['rule']})")
    for calibration, phase in real_sphere.COMBINATIONS:
        row = report["ours"][real_sphere.combination_key(calibration, phase)]
        edge = row["edge_band_removed"]
        print(f"  {calibration:12s}{phase:8s}{row['rms_um']:9.3f}{row['radius_mm']:11.4f}{row['points']:8d}"
              f"   {edge['rms_um']:7.3f} um  {edge['radius_mm']:.4f} mm  {edge['points']} points")
    return 0
