"""``dptpu eval sphere``: the paper's Fig. 3 figures and the project's own reconstruction of the real sphere.

``dptpu eval unwrap [--model PATH ...] [--unet PATH] --out DIR``: fringe-order accuracy on the paper's unseen
dynamic rig, solvers side by side (:mod:`dptpu.experiments.unwrap_eval`); ``--frequencies 16,56,96 --scenes 1
--size 160x120`` gives a tiny set.

``dptpu eval cloud [--rigs all] [--scenes N] [--size WxH] [--cfpe-scenes 01,04,06,08] --out DIR``: precision and
completeness of the published points per method, solver and noise on twin rigs the model was not trained on, and on
the real CFPE captures (:mod:`dptpu.experiments.cloud_eval`); the defaults are one tiny scene (seconds).
"""
from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

from dptpu.fpp.measured_data import shared_data_dir


def register(subparsers) -> None:
    parser = subparsers.add_parser("eval", help="evaluate against reference data")
    targets = parser.add_subparsers(dest="target", metavar="TARGET", required=True)
    sphere = targets.add_parser("sphere", help="the DP-TPU standard sphere (paper Fig. 3) on real data")
    sphere.add_argument("--data", help="dptpu-sphere folder (default: $DPTPU_DATA/dptpu-sphere or "
                                       "../shared/data/dptpu-sphere)")
    sphere.add_argument("--json", action="store_true", help="print the figures as JSON")
    sphere.add_argument("--quiet", action="store_true", help="no progress bar")
    sphere.set_defaults(func=run_sphere)
    _register_unwrap(targets)
    _register_cloud(targets)


def _register_cloud(targets) -> None:
    cloud = targets.add_parser(
        "cloud", help="precision and completeness of the published points on unseen rigs and real CFPE captures",
        description="Render random scenes of several objects on rigs the model was not trained on (supersampled: "
                    "mixed pixels at depth edges), 12-step and 3-step, noise 0/1/2 sigma; unwrap by MF, MW and NT, "
                    "classical and DP-TPU, triangulate, and score the published points against the truth: the share "
                    "with a wrong fringe order or off the true surface, and the share of the truly valid pixels "
                    "published. With CFPE scenes: the real captures' 3-step heterodyne against the 12-step order. "
                    "Writes cloud_eval.md and cloud_eval.json to --out.")
    cloud.add_argument("--out", required=True, type=Path, metavar="DIR", help="output folder")
    cloud.add_argument("--model", action="append", default=None, metavar="PATH",
                       help="DP-TPU model (.onnx), repeatable; default the shipped model; 'none' for classical only")
    cloud.add_argument("--rigs", default=None,
                       help="outside rigs by name, comma separated, or 'all' (default: the first, f1800-b150-14deg)")
    cloud.add_argument("--scenes", type=int, default=1, help="random scenes per rig (default 1)")
    cloud.add_argument("--size", default="96x72", help="camera size WIDTHxHEIGHT (default 96x72)")
    cloud.add_argument("--frequency", type=float, default=16.0,
                       help="high frequency f_h (default 16, for the default 96x72; the full run: 64 at 320x240)")
    cloud.add_argument("--steps", default="12,3", help="phase steps, comma separated (default 12,3)")
    cloud.add_argument("--noise", default="0,1,2", help="camera noise in the paper's sigmas (1.5693 DN), "
                                                      "comma separated (default 0,1,2)")
    cloud.add_argument("--methods", default="mf,mw,nt", help="methods, comma separated (default mf,mw,nt)")
    cloud.add_argument("--supersample", type=int, default=3, help="rays per pixel along each axis (default 3)")
    cloud.add_argument("--seed", type=int, default=None, help="scene seed root (default 500, unseen in training)")
    cloud.add_argument("--cfpe", default=None, metavar="DIR",
                       help="CFPE frames folder (default $DPTPU_DATA/cfpe or ../shared/data/cfpe; 'none' to skip)")
    cloud.add_argument("--cfpe-scenes", default="", help="CFPE scenes, comma separated, e.g. 01,04,06,08 "
                                                         "(default none: the real captures take longer)")
    cloud.add_argument("--min-confidence", type=float, default=None, metavar="C",
                       help="drop pixels of lower confidence, as dptpu triangulate (default its default; 0 keeps all)")
    cloud.add_argument("--keep-edges", action="store_true",
                       help="keep the points at depth edges (default: dropped, as dptpu triangulate does)")
    cloud.add_argument("--keep-islands", action="store_true",
                       help="keep the islands of a wrong fringe order (default: dropped, as dptpu triangulate does; "
                            "docs/nodes.md 'Order islands')")
    cloud.add_argument("--threads", type=int, default=None, help="onnxruntime threads")
    cloud.add_argument("--quiet", action="store_true", help="no progress bars")
    cloud.set_defaults(func=run_cloud)


def run_cloud(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.experiments.cloud_eval import DEFAULT_SEED, OUTSIDE_RIGS, CloudEvalSpec, EvalRig, run_cloud_eval
    from dptpu.sim.rig import parse_size

    rigs = {r.name: r for r in OUTSIDE_RIGS}
    chosen: tuple[EvalRig, ...]
    if args.rigs is None:
        chosen = OUTSIDE_RIGS[:1]
    elif args.rigs == "all":
        chosen = OUTSIDE_RIGS
    else:
        names = [n.strip() for n in args.rigs.split(",") if n.strip()]
        unknown = [n for n in names if n not in rigs]
        if unknown or not names:
            raise ValueError(f"--rigs: unknown rig(s) {', '.join(unknown) or repr(args.rigs)}; known: "
                             f"{', '.join(rigs)} or all")
        chosen = tuple(rigs[n] for n in names)
    steps = tuple(int(s) for s in _numbers(args.steps, "--steps"))
    spec = CloudEvalSpec(rigs=chosen, scenes=args.scenes, size=parse_size(args.size), frequency=args.frequency,
                         steps=steps, noise_sigmas=_numbers(args.noise, "--noise"),
                         methods=tuple(m.strip() for m in args.methods.split(",") if m.strip()),
                         supersample=args.supersample, seed=DEFAULT_SEED if args.seed is None else args.seed,
                         cfpe_scenes=tuple(s.strip() for s in args.cfpe_scenes.split(",") if s.strip()),
                         edges=not args.keep_edges, islands=not args.keep_islands,
                         **({} if args.min_confidence is None else {"min_confidence": args.min_confidence}))
    cfpe_dir = None
    if spec.cfpe_scenes and (args.cfpe is None or args.cfpe.lower() != "none"):
        cfpe_dir = Path(args.cfpe) if args.cfpe else shared_data_dir() / "cfpe"
        if not cfpe_dir.is_dir():
            raise FileNotFoundError(f"{cfpe_dir}: no CFPE folder (pass --cfpe DIR or --cfpe-scenes '')")
    args.unet = None
    models = _load_models(args)
    command = "dptpu " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if len(sys.argv) > 1 else ""
    result = run_cloud_eval(spec, args.out, models=models, cfpe_dir=cfpe_dir, command=command,
                            progress=not args.quiet)
    print(result.table)
    print("wrote " + ", ".join(str(p) for p in result.files.values()))
    return 0


def _register_unwrap(targets) -> None:
    unwrap = targets.add_parser(
        "unwrap", help="fringe-order accuracy on the paper's unseen dynamic rig: classical, median, U-Net, DP-TPU",
        description="Render a test set on an unseen rig (default: the paper's dynamic rig) with unseen random "
                    "scenes, f_h = 16..96 step 4, MF/MW/NT, 1 and 2 sigma noise, 3-step inputs and 12-step labels; "
                    "evaluate the classical order, its 3x3 median, the U-Net baseline and DP-TPU; write table.csv, "
                    "heatmap.png (Fig. 4b), error_vs_frequency.png (Fig. 6) and summary.md to --out.")
    unwrap.add_argument("--model", action="append", default=None, metavar="PATH",
                        help="DP-TPU model (.onnx), repeatable; default the shipped model; 'none' for no model")
    unwrap.add_argument("--unet", default=None, metavar="PATH", help="U-Net baseline model (.onnx), optional")
    unwrap.add_argument("--out", required=True, type=Path, metavar="DIR", help="output folder")
    unwrap.add_argument("--data", default=None, type=Path, metavar="DIR",
                        help="evaluate an existing test set (e.g. DIR/testset of an earlier run) instead of rendering")
    unwrap.add_argument("--rig", default="dynamic", help="rig preset or file for the test set (default dynamic)")
    unwrap.add_argument("--renderer", choices=("raycast", "blender"), default="raycast",
                        help="renderer of the test scenes (default raycast; blender needs 'dptpu sim setup-blender')")
    unwrap.add_argument("--frequencies", default=None,
                        help="high frequencies, comma separated (default 16,20,...,96)")
    unwrap.add_argument("--noise", default=None, help="noise levels in gray levels, comma separated "
                                                      "(default 1.5693,3.1386)")
    unwrap.add_argument("--scenes", type=int, default=2, help="random scenes (default 2)")
    unwrap.add_argument("--size", default="640x480", help="camera size WIDTHxHEIGHT (default 640x480)")
    unwrap.add_argument("--seed", type=int, default=None, help="scene seed root (default 300, unseen in training)")
    unwrap.add_argument("--blender-samples", type=int, default=8, help="Cycles samples per pixel (default 8)")
    unwrap.add_argument("--workers", type=int, default=1, help="processes rendering scenes (default 1)")
    unwrap.add_argument("--vote-baseline", action="store_true",
                        help="add the solver classical+vote: the consensus vote on DP-TPU's prior alone, no network")
    unwrap.add_argument("--threads", type=int, default=None, help="onnxruntime threads")
    unwrap.add_argument("--quiet", action="store_true", help="no progress bar")
    unwrap.set_defaults(func=run_unwrap)


def _numbers(text, option) -> tuple:
    try:
        values = tuple(float(v) for v in str(text).split(",") if v.strip())
    except ValueError:
        values = ()
    if not values:
        raise ValueError(f"{option} must be comma-separated numbers (e.g. 16,56,96); got {text!r}")
    return values


def _load_models(args) -> list:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.models.inference import FringeOrderModel, shipped_model_path

    paths = args.model if args.model is not None else [shipped_model_path()]
    if any(str(p).lower() == "none" for p in paths):
        if len(paths) > 1:
            raise ValueError(f"--model none cannot be combined with other --model paths; got {paths}")
        paths = []
    paths = [p for p in paths if p is not None]  # no shipped model: classical solvers only
    if args.unet is not None:
        paths.append(args.unet)
    return [FringeOrderModel.load(p, threads=args.threads) for p in paths]


def run_unwrap(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.experiments.unwrap_eval import (
        DEFAULT_SEED,
        EVAL_FREQUENCIES,
        EVAL_NOISE,
        UnwrapEvalSpec,
        run_unwrap_eval,
    )
    from dptpu.sim.rig import parse_size

    models = _load_models(args)
    spec = UnwrapEvalSpec(
        frequencies=_numbers(args.frequencies, "--frequencies") if args.frequencies else EVAL_FREQUENCIES,
        noise=_numbers(args.noise, "--noise") if args.noise else EVAL_NOISE, scenes=args.scenes,
        size=parse_size(args.size), seed=DEFAULT_SEED if args.seed is None else args.seed, rig=args.rig,
        renderer=args.renderer, blender_samples=args.blender_samples)
    command = "dptpu " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if len(sys.argv) > 1 else ""
    result = run_unwrap_eval(spec, args.out, models=models, data_dir=args.data, workers=args.workers,
                             progress=not args.quiet, command=command, vote_baseline=args.vote_baseline)
    print(result.files["summary"].read_text())
    print("wrote " + ", ".join(str(p) for p in result.files.values()))
    return 0


def run_sphere(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.fpp import real_sphere

    data_dir = args.data or shared_data_dir() / "dptpu-sphere"
    report = real_sphere.evaluate(data_dir, progress=not args.quiet)
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
