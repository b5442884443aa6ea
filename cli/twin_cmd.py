"""``dptpu twin ...``: hold measured data against the digital twin.

``dptpu twin diagnose --measured PATH --rig RIG [--reference sphere:DIAMETER_MM | plane | scene:FILE]
[--self-reference] [--frequency F] --out DIR`` (:mod:`dptpu.sim.diagnosis`, docs/sim-to-real.md): registration,
residuals and their decomposition (PNG figures), candidate effects ranked by BIC, the extended rig, the re-render and
``report.json`` / ``report.md``; a progress bar on stderr (``--quiet``: none) and a short summary on stdout.

``dptpu twin finetune --measured DATA --extended RIG --model BASE --out DIR``
(:mod:`dptpu.experiments.downstream`): the downstream gain of the extended twin on measured data.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from .conventions import parse_list


def register(subparsers) -> None:
    parser = subparsers.add_parser("twin", help="sim-to-real: what the twin gets wrong on measured data")
    twin_subparsers = parser.add_subparsers(dest="twin_command", metavar="TWIN_COMMAND", required=True)
    diagnose = twin_subparsers.add_parser(
        "diagnose", help="diagnose measured data against the twin: cause, fitted effects, extended rig, gain",
        description="Register the reference object (or use the data's own phase with --self-reference), fit each "
                    "effect of the twin's vocabulary with the twin in the loop, rank them by BIC, write the "
                    "extended rig, render again and report (report.json, report.md, PNG figures). "
                    "See docs/sim-to-real.md.")
    diagnose.add_argument("--measured", required=True,
                          help="capture folder (raw frames), .npz phase file (absolute_phase, frequency, "
                               "fringe_axis, projector_size) or a dptpu-sphere .mat phase file (with --frequency)")
    diagnose.add_argument("--rig", default=None,
                          help="dptpu-rig/1 or OpenCV rig file, 'CAM.mat,PRJ.mat' (Bouguet) or 'nominal'; "
                               "optional with --self-reference")
    diagnose.add_argument("--reference", default=None,
                          help="sphere:DIAMETER_MM, plane or scene:FILE (a dptpu scene YAML, docs/twin.md: its pose "
                               "is registered from the data by ICP)")
    diagnose.add_argument("--self-reference", action="store_true",
                          help="no calibration or reference object: the data's own 12-step phase is the reference")
    diagnose.add_argument("--frequency", type=float, default=None,
                          help="fringe frequency of a .mat phase file (96 for dptpu-sphere)")
    diagnose.add_argument("--max-pixels", type=int, default=12000,
                          help="pixels used by the photometric fits (default 12000, a seeded random subset)")
    diagnose.add_argument("--rounds", type=int, default=3,
                          help="photometric effects found greedily, the cause first (default 3)")
    diagnose.add_argument("--seed", type=int, default=0, help="seed of the twin's renders (default 0)")
    diagnose.add_argument("--no-rerender", action="store_true", help="skip rendering the twins again")
    diagnose.add_argument("--quiet", action="store_true", help="no progress bar on stderr")
    diagnose.add_argument("--out", required=True, help="output folder")
    diagnose.set_defaults(func=run_diagnose)

    finetune = twin_subparsers.add_parser(
        "finetune", help="downstream gain: fine-tune DP-TPU on the extended and on the baseline twin, score on "
                         "measured data",
        description="Build the network's inputs from measured data (CFPE frames or the dptpu-sphere phase), render "
                    "two twin sets of the same scenes (baseline rig, extended rig), fine-tune the base model on "
                    "each with the same budget, and compare fringe-order accuracy (and the sphere's 3D error). "
                    "Writes downstream.json and report.md. See docs/sim-to-real.md, 'Downstream gain'.")
    finetune.add_argument("--measured", required=True, help="../shared/data/cfpe or ../shared/data/dptpu-sphere")
    finetune.add_argument("--extended", required=True,
                          help="extended_rig.yaml or extended_effects.yaml of 'dptpu twin diagnose', or "
                               "cfpe-response: the CFPE projector's response measured on the frames")
    finetune.add_argument("--rig", default=None, help="rig for an effects file (default nominal)")
    finetune.add_argument("--model", required=True, help="base model: exported .onnx or a training .ckpt")
    finetune.add_argument("--scenes", type=int, default=8, help="twin scenes per training set (default 8)")
    finetune.add_argument("--size", default="320x240", help="twin camera WIDTHxHEIGHT (default 320x240)")
    finetune.add_argument("--epochs", type=int, default=60, help="fine-tune epochs, the same for both (default 60)")
    finetune.add_argument("--batch", type=int, default=4, help="samples per step (default 4)")
    finetune.add_argument("--lr", type=float, default=3e-4, help="AdamW learning rate (default 3e-4)")
    finetune.add_argument("--noise", default="1.5693,3.1386",
                          help="camera noise of the twin sets, DN, comma separated (default 1.5693,3.1386: the "
                               "paper's 1 and 2 sigma)")
    finetune.add_argument("--huber", type=float, default=None,
                          help="Huber threshold of the loss, fringe orders (default none: squared error)")
    finetune.add_argument("--max-correction", default=None,
                          help="training labels kept only within this many orders of the classical order, or "
                               "'none' for every label (default: the pair design's, 4 for CFPE)")
    finetune.add_argument("--cfpe-scenes", default="01,04,06,08", help="CFPE scenes, comma separated (default "
                          "01,04,06,08)")
    finetune.add_argument("--cfpe-low", default="cascade", choices=("cascade", "het12", "beat123"),
                          help="CFPE pairs: cascade (default: the heterodyne as two MF pairs, every solver at each "
                               "level, sim/diagnosis/beat_cascade.py), or one pair with the low phase het12 or "
                               "beat123 (sim/diagnosis/cfpe_inputs.py)")
    finetune.add_argument("--seed", type=int, default=0, help="seed of scenes and training (default 0)")
    finetune.add_argument("--threads", type=int, default=1, help="torch and onnxruntime threads (default 1)")
    finetune.add_argument("--out", required=True, help="output folder")
    finetune.add_argument("--quiet", action="store_true",
                          help="no progress bars or lines on stderr (the summary stays)")
    finetune.set_defaults(func=run_finetune)


def run_diagnose(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from tqdm import tqdm

    from dptpu.sim.diagnosis import diagnose
    from dptpu.sim.diagnosis.measured import load_measured
    from dptpu.sim.diagnosis.report import write_report
    from dptpu.sim.diagnosis.summary import human_summary
    from dptpu.sim.rig import load_twin_rig

    if args.self_reference and args.reference:
        raise ValueError("give either --reference or --self-reference, not both")
    if not args.self_reference and not args.reference:
        raise ValueError("--reference sphere:DIAMETER_MM | plane | scene:FILE is required (or --self-reference)")
    if args.rig is None and not args.self_reference:
        raise ValueError("--rig is required with --reference")
    if args.rounds < 1:
        raise ValueError(f"--rounds must be >= 1; got {args.rounds}")
    if args.max_pixels < 100:
        raise ValueError(f"--max-pixels must be >= 100; got {args.max_pixels}")
    measured = load_measured(args.measured, frequency=args.frequency, decode=not args.self_reference)
    rig = None
    if args.rig is not None:
        rig = load_twin_rig(args.rig)
        shape = measured.absolute_phase.shape
        width, height = rig.camera.size
        if (width, height) != (shape[1], shape[0]) and width * shape[0] == height * shape[1]:
            rig = load_twin_rig(args.rig, size=(shape[1], shape[0]))  # same aspect: K rescaled (docs/twin.md)
        elif (width, height) != (shape[1], shape[0]):
            raise ValueError(f"{args.rig}: camera size {rig.camera.size[0]}x{rig.camera.size[1]} does not match the "
                             f"measured data's {shape[1]}x{shape[0]}")
    with tqdm(unit="step", file=sys.stderr, disable=args.quiet,
              bar_format="diagnose: step {n_fmt} [{elapsed}] {desc}") as bar:

        def progress(label: str) -> None:
            bar.set_description_str(label, refresh=False)
            bar.update(1)

        result = diagnose(measured, rig, reference=args.reference, self_reference=args.self_reference,
                          max_pixels=args.max_pixels, seed=args.seed, outside_vocabulary=True,
                          rounds=args.rounds, progress=progress)
        progress("writing the report" if args.no_rerender else "rendering the twins again, writing the report")
        report = write_report(result, args.out, rerender=not args.no_rerender)
        progress("done")
    print(human_summary(report, result.extended_effects))
    print(f"report: {Path(args.out) / 'report.json'}, {Path(args.out) / 'report.md'}")
    return 0


def run_finetune(args) -> int:
    import torch  # training only

    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from tqdm import tqdm

    from dptpu.experiments.downstream import DownstreamOptions, run_downstream
    from dptpu.experiments.finetune import FinetuneOptions

    noise = parse_list(args.noise, "--noise", float)
    if any(not sigma >= 0 for sigma in noise):
        raise ValueError(f"--noise must list sigmas >= 0 (DN); got {args.noise!r}")
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size must be WIDTHxHEIGHT (e.g. 320x240); got {args.size!r}") from None
    if args.threads < 1:
        raise ValueError(f"--threads must be >= 1; got {args.threads}")
    torch.set_num_threads(args.threads)
    max_correction: int | None = -1  # the design's
    if args.max_correction is not None:
        if args.max_correction.lower() == "none":
            max_correction = None
        elif args.max_correction.isdigit():
            max_correction = int(args.max_correction)
        else:
            raise ValueError(f"--max-correction must be a whole number of orders >= 0 or 'none'; got "
                             f"{args.max_correction!r}")
    options = DownstreamOptions(scenes=args.scenes, size=(width, height), seed=args.seed, noise=noise,
                                cfpe_scenes=tuple(s.strip() for s in args.cfpe_scenes.split(",") if s.strip()),
                                cfpe_low=args.cfpe_low, max_correction=max_correction,
                                finetune=FinetuneOptions(epochs=args.epochs, batch=args.batch, lr=args.lr,
                                                         seed=args.seed, huber=args.huber))
    # each stage's line through tqdm.write: printed above the bars (the twin sets' scenes, the epochs, the scoring)
    report = run_downstream(args.measured, args.extended, args.out, model=args.model, base_rig=args.rig,
                            options=options, threads=args.threads, progress=not args.quiet,
                            log=(lambda text: None) if args.quiet else (lambda text: tqdm.write(text, file=sys.stderr)))
    print(json.dumps(report["summary"], indent=2))
    return 0
