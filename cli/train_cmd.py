"""``dptpu train`` and ``dptpu model export|eval|toy-data``: the DP-TPU network's command line.

    dptpu train --data DIR --out models/dptpu.onnx [--epochs E --batch B --crop-size WIDTHxHEIGHT --seed S
                --model dptpu|unet --resume CKPT --lambda-fourier 0.1 --threads N --time-limit-min M]
    torchrun --nproc_per_node 2 -m dptpu.cli.main train ...      (data parallel, gloo on CPU)
    dptpu model export --checkpoint CKPT --out MODEL.onnx [--quiet]
    dptpu model eval --data DIR [--model MODEL.onnx ...] --out DIR
    dptpu model toy-data --out DIR [--scenes N --frequencies 32,48,64,80 --methods mf,mw,nt --size WIDTHxHEIGHT ...]
    dptpu model study --out DIR [--sets S1,...,S5 --methods mf,mw --scenes N --steps T ...]

Thin shell over :mod:`dptpu.models`; torch is imported only by ``train`` and ``model export``. Sizes are
``WIDTHxHEIGHT`` and lists comma separated (:mod:`dptpu.cli.conventions`).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from dptpu.cli.conventions import add_quiet_option, add_renamed_option, parse_list, parse_size, stage_bar


def _size(option: str):
    """An argparse type: ``WIDTHxHEIGHT`` -> ``(height, width)``, the models' (rows, columns) order."""
    def parse(text: str) -> tuple[int, int]:
        try:
            width, height = parse_size(text, option)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return height, width
    return parse


def _floats(text: str) -> list[float]:
    try:
        return list(parse_list(text, "the list", float, example="32,48,64,80"))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "train", help="train DP-TPU (or the U-Net baseline) on a dptpu-dataset/1 folder -> ONNX",
        description="Train on a twin dataset (dptpu sim dataset) with AdamW and the joint spatial-Fourier loss "
                    "(Eqs. 15-17), checkpoint every epoch, export ONNX at the end. Under torchrun the processes "
                    "train data-parallel (DDP, gloo).")
    parser.add_argument("--data", required=True, type=Path, metavar="DIR", help="dptpu-dataset/1 folder")
    parser.add_argument("--out", required=True, type=Path, metavar="MODEL.onnx", help="ONNX file to write")
    parser.add_argument("--epochs", type=int, default=1, help="total epochs (default 1)")
    parser.add_argument("--batch", type=int, default=4, help="samples per step and process (default 4)")
    parser.add_argument("--crop-size", dest="crop", type=_size("--crop-size"), default=(64, 64), metavar="WIDTHxHEIGHT",
                        help="training crop (default 64x64)")
    add_renamed_option(parser, "--crop", "write --crop-size WIDTHxHEIGHT (width first; --crop was HEIGHTxWIDTH)")
    parser.add_argument("--seed", type=int, default=0, help="seed of weights, crops and order (default 0)")
    parser.add_argument("--model", choices=("dptpu", "unet"), default="dptpu",
                        help="dptpu (physics priors) or unet (wrapped phases only)")
    parser.add_argument("--config", type=json.loads, metavar="JSON",
                        help='architecture, e.g. \'{"widths": [16, 32, 48, 64]}\' (DPTPUConfig / UNetConfig keys)')
    parser.add_argument("--resume", type=Path, metavar="CKPT", help="continue from this checkpoint")
    parser.add_argument("--checkpoint", type=Path, metavar="CKPT", help="checkpoint file (default: OUT with .ckpt)")
    parser.add_argument("--lr", type=float, default=1e-3, help="AdamW learning rate (default 1e-3)")
    parser.add_argument("--lambda-fourier", type=float, default=0.1,
                        help="weight of the Fourier term, lambda2 of Eq. 15 (default 0.1; 0 = ablation)")
    parser.add_argument("--lambda-mse", type=float, default=0.9, help="weight of the MSE term (default 0.9)")
    parser.add_argument("--huber", type=float, metavar="ORDERS",
                        help="Huber threshold of the spatial term in fringe orders (default: plain MSE, the paper)")
    parser.add_argument("--threads", type=int, metavar="N", help="torch intra-op threads per process")
    parser.add_argument("--time-limit-min", type=float, metavar="M",
                        help="stop after the first epoch that ends past M minutes")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=run_train)

    model = subparsers.add_parser("model", help="export, evaluate, or make toy data for the DP-TPU network")
    actions = model.add_subparsers(dest="action", metavar="ACTION", required=True)
    export = actions.add_parser("export", help="training checkpoint -> ONNX (dynamic height and width)")
    export.add_argument("--checkpoint", required=True, type=Path, metavar="CKPT",
                        help="training checkpoint (.ckpt) written by dptpu train")
    export.add_argument("--out", required=True, type=Path, metavar="MODEL.onnx", help="ONNX file to write")
    add_quiet_option(export, "no progress line on stderr (its stages: reading the checkpoint, exporting)")
    export.set_defaults(func=run_export)

    evaluate = actions.add_parser("eval", help="fringe-order accuracy: classical, median, models -> table.csv")
    evaluate.add_argument("--data", required=True, type=Path, metavar="DIR", help="held-out dptpu-dataset/1 folder")
    evaluate.add_argument("--model", action="append", default=[], type=Path, metavar="MODEL.onnx",
                          help="an exported model (repeatable); default: the shipped model, if any")
    evaluate.add_argument("--out", required=True, type=Path, metavar="DIR", help="folder for table.csv, summary.md")
    evaluate.add_argument("--threads", type=int, metavar="N", help="onnxruntime threads")
    evaluate.add_argument("--quiet", action="store_true", help="no progress bar")
    evaluate.set_defaults(func=run_eval)

    toy = actions.add_parser("toy-data", help="a dptpu-dataset/1 folder of analytic step scenes (not the twin)")
    toy.add_argument("--out", required=True, type=Path, metavar="DIR", help="dataset folder to write")
    toy.add_argument("--scenes", type=int, default=2, help="scenes per (method, frequency) (default 2)")
    toy.add_argument("--frequencies", type=_floats, default=[32, 48, 64, 80], metavar="F,F,...",
                     help="high frequencies (default the paper's S4: 32,48,64,80)")
    toy.add_argument("--methods", default="mf,mw,nt", help="comma-separated of mf, mw, nt (default all)")
    toy.add_argument("--noise", type=_floats, default=[1.5693], metavar="SIGMA,...",
                     help="camera noise in gray levels (default 1.5693, the paper's 1 sigma)")
    toy.add_argument("--size", dest="shape", type=_size("--size"), default=(96, 128), metavar="WIDTHxHEIGHT",
                     help="sample size (default 128x96)")
    add_renamed_option(toy, "--shape", "write --size WIDTHxHEIGHT (width first; --shape was HEIGHTxWIDTH)")
    toy.add_argument("--steps", type=int, default=3, help="phase steps of the inputs (default 3)")
    toy.add_argument("--seed", type=int, default=0, help="seed of the scenes and the noise (default 0)")
    toy.add_argument("--quiet", action="store_true", help="no progress bar")
    toy.set_defaults(func=run_toy_data)

    from dptpu.experiments.study import add_study_arguments, run_study_command  # no torch at import

    study = actions.add_parser("study", help="the paper's training-frequency study (S1-S5) and Fourier ablation",
                               description="Train one DP-TPU model per frequency set on the same twin scenes "
                                           "and step budget, test on unseen scenes -> table.csv, boxplots, "
                                           "summary.md (dptpu.experiments.study).")
    add_study_arguments(study)
    add_renamed_option(study, "--crop", "write --crop-size WIDTHxHEIGHT (width first; --crop was HEIGHTxWIDTH)")
    study.set_defaults(func=run_study_command)


def run_train(args: argparse.Namespace) -> int:
    import torch  # training only

    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.models.loss import LossWeights
    from dptpu.models.training import TrainOptions, train

    if args.threads:
        torch.set_num_threads(args.threads)
    options = TrainOptions(
        data_dir=args.data, out=args.out, epochs=args.epochs, batch=args.batch, crop=args.crop, seed=args.seed,
        model=args.model, config=args.config, lr=args.lr,
        loss=LossWeights(args.lambda_mse, args.lambda_fourier, args.huber),
        checkpoint=args.checkpoint, resume=args.resume,
        time_limit_s=None if args.time_limit_min is None else 60.0 * args.time_limit_min, progress=not args.quiet)
    result = train(options)
    if result.onnx is not None:
        last = result.history[-1] if result.history else {}
        print(f"{args.model}: {result.epochs_done} epochs, {result.parameters} parameters, "
              f"{result.world_size} process(es), {result.seconds:.1f} s, "
              f"final loss {last.get('loss', float('nan')):.5f} "
              f"-> {result.onnx} (checkpoint {result.checkpoint})")
    return 0


def run_export(args: argparse.Namespace) -> int:
    with stage_bar("model export", quiet=args.quiet) as step:  # seconds: torch's import, the export and its check
        step(f"reading {args.checkpoint}")
        # imported when the command runs, not at start-up: keeps `dptpu --help` fast
        from dptpu.models.export import export_onnx, load_checkpoint_model

        model, checkpoint = load_checkpoint_model(args.checkpoint)
        step(f"exporting to {args.out}")
        training = {**checkpoint.get("options", {}), **checkpoint.get("dataset", {}),
                    "epochs_done": checkpoint["epoch"]}
        out = export_onnx(model, args.out, training=training)
        step("done")
    print(f"{checkpoint['kind']} (epoch {checkpoint['epoch']}) -> {out}")
    return 0


def run_eval(args: argparse.Namespace) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.models.evaluate import evaluate_dataset, format_summary, write_table
    from dptpu.models.inference import shipped_model_path

    models = list(args.model)
    if not models and shipped_model_path() is not None:
        models = [shipped_model_path()]
    args.out.mkdir(parents=True, exist_ok=True)
    rows = evaluate_dataset(args.data, models, threads=args.threads, progress=not args.quiet)
    write_table(rows, args.out / "table.csv")
    summary = format_summary(rows)
    (args.out / "summary.md").write_text(
        f"# Fringe-order accuracy (%) on {args.data}\n\nModels: {', '.join(str(m) for m in models) or 'none'}\n\n"
        + summary)
    sys.stdout.write(summary)
    return 0


def run_toy_data(args: argparse.Namespace) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.models.toy_dataset import write_toy_dataset

    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    for m in methods:
        if m not in ("mf", "mw", "nt"):
            raise ValueError(f"--methods takes mf, mw, nt; got {m!r}")
    out = write_toy_dataset(args.out, frequencies=tuple(args.frequencies), methods=methods, scenes=args.scenes,
                            shape=args.shape, noise_sigmas=tuple(args.noise), steps=args.steps, seed=args.seed,
                            progress=not args.quiet)
    print(f"toy dataset -> {out}")
    return 0
