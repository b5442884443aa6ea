"""``dptpu sim dataset``: a training dataset (``dptpu-dataset/1``) rendered by the twin (docs/dataset.md).

    dptpu sim dataset --rig RIG [--rig RIG2 ...] --frequencies 32,48,64,80 --methods mf,mw,nt --scenes N --input-steps 3
        --label-steps 12 --noise SIGMA,... --out DIR [--shard I/N] [--workers K] [--size WIDTHxHEIGHT] [--seed S]
        [--meshes DIR] [--quiet]
"""
from __future__ import annotations

from pathlib import Path

from dptpu.cli.conventions import parse_list


def _numbers(text: str, what: str) -> list[float]:
    try:
        values = [float(v) for v in str(text).split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--{what} must be comma-separated numbers, e.g. 32,48,64,80; got {text!r}") from None
    if not values:
        raise ValueError(f"--{what} must list at least one number; got {text!r}")
    return values


def rig_sources(values) -> list[tuple[str, str]]:
    """``--rig`` values -> ``[(name, source), ...]`` for :func:`dptpu.sim.rig.load_twin_rig`.

    Each value is a preset (``nominal``, ``wide``, ...), a rig file or a Bouguet pair ``CAM.mat,PRJ.mat``; a value
    whose comma-separated parts are all presets (``nominal,wide``) names several rigs. Names: the preset, or the
    file's stem (the camera file's for a Bouguet pair).
    """
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.sim.rig import RIG_PRESETS

    sources = []
    for value in values:
        parts = [p.strip() for p in str(value).split(",")]
        if len(parts) > 1 and all(p in RIG_PRESETS for p in parts):
            sources += [(p, p) for p in parts]
        elif str(value) in RIG_PRESETS:
            sources.append((str(value), str(value)))
        else:
            sources.append((Path(parts[0]).stem or "rig", str(value)))
    names = [name for name, _ in sources]
    if len(set(names)) != len(names):
        raise ValueError(f"--rig: each rig may be given once (names {names})")
    return sources


def register(sim_subparsers) -> None:
    parser = sim_subparsers.add_parser(
        "dataset", help="render a training dataset (dptpu-dataset/1) with the twin",
        description="Random scenes x frequencies x methods x noise levels; per sample the wrapped phases and the "
                    "classical coarse order from noisy few-step frames, and the label fringe order from 12-step "
                    "frames checked against the ray cast (docs/dataset.md).")
    parser.add_argument("--rig", required=True, action="append",
                        help="dptpu-rig/1 or OpenCV rig file, 'CAM.mat,PRJ.mat' (Bouguet), or a preset ('nominal', "
                             "'wide', 'dynamic'); repeat it or give 'nominal,wide' to split the scenes among rigs")
    parser.add_argument("--frequencies", default="32,48,64,80",
                        help="high frequencies, periods across the projector width (default 32,48,64,80: S4)")
    parser.add_argument("--methods", default="mf,mw,nt", help="TPU methods, comma separated (default mf,mw,nt)")
    parser.add_argument("--scenes", type=int, required=True, help="number of random scenes")
    parser.add_argument("--input-steps", type=int, default=3, help="phase steps of the noisy inputs (default 3)")
    parser.add_argument("--label-steps", type=int, default=12, help="phase steps of the labels (default 12)")
    parser.add_argument("--noise", nargs="+", default=["1.5693"], metavar="SIGMA,...",
                        help="camera noise levels in gray levels, comma separated, each rendered for every scene "
                             "(default 1.5693)")
    parser.add_argument("--size", default=None, help="camera size WIDTHxHEIGHT (default: the rig's; K is rescaled)")
    parser.add_argument("--seed", type=int, default=0, help="root of the scene seeds (default 0)")
    parser.add_argument("--meshes", default=None, help="folder of meshes (e.g. Thingi10K) for the random scenes")
    parser.add_argument("--shard", default="0/1", help="I/N: render only the scenes i with i %% N == I (default 0/1)")
    parser.add_argument("--workers", type=int, default=1, help="processes rendering scenes in parallel (default 1)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--out", required=True, help="dataset folder")
    parser.set_defaults(func=run)


def run(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.fpp.dataset import open_dataset
    from dptpu.sim.dataset import DatasetSpec, parse_shard, write_dataset
    from dptpu.sim.rig import load_twin_rig, parse_size

    shard = parse_shard(args.shard)
    sources = rig_sources(args.rig)
    rigs = [(name, load_twin_rig(source)) for name, source in sources]
    if len(args.noise) > 1:  # the old space-separated spelling
        raise ValueError(f"--noise takes one comma-separated list: --noise {','.join(args.noise)} "
                         f"(space-separated values are no longer accepted)")
    noise = parse_list(args.noise[0], "--noise", float)
    size = parse_size(args.size) if args.size else tuple(rigs[0][1].camera.size)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    spec = DatasetSpec(frequencies=tuple(_numbers(args.frequencies, "frequencies")), methods=tuple(methods),
                       scenes=args.scenes, input_steps=args.input_steps, label_steps=args.label_steps,
                       noise=noise, size=size, seed=args.seed, meshes=args.meshes)
    out = write_dataset(rigs, spec, args.out, shard=shard, workers=args.workers, progress=not args.quiet)
    dataset = open_dataset(out)
    print(f"{out}: {len(dataset)} of {spec.count} samples on disk (shard {shard[0]}/{shard[1]}; "
          f"{spec.per_scene} per scene, {size[0]}x{size[1]}, rigs {', '.join(dataset.rig_names)})")
    return 0
