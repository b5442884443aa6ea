"""The paper's training-frequency study (S1-S5, Fig. 4c) and the Fourier-loss ablation, at any scale.

    dptpu model study --out DIR [--sets S1,S2,S3,S4,S5] [--methods mf,mw,nt] [--scenes N --size WIDTHxHEIGHT
                      --steps T --batch B --crop-size WIDTHxHEIGHT --seed S --ablation-seeds 0,1 ...]

One study is a list of :class:`StudyRun` (one DP-TPU model each) that differ only where they must:

* the frequency-set runs ``S1`` ... ``S5`` differ only in the high frequencies of their training samples.
  All of them are cut from ONE twin dataset (the "pool": the same random scenes, methods and noise levels,
  rendered once at the union of the sets' frequencies; MF f_l = 1, MW f_l = f_h - 1, NT f_l = 10.9), and
  all train for the same number of optimizer steps (:func:`equal_step_epochs`). A set with more
  frequencies has more distinct samples, so it runs fewer epochs over them;
* the ablation runs are the ablation set (S4) with lambda2 = 0 (Eq. 15 without the Fourier term of
  Eqs. 16-17) next to the same set with lambda2 = 0.1, for each ablation seed: equal in data, steps, crops
  and initial weights, different in lambda2 only.

Every model is evaluated on one held-out twin set of unseen scenes (another scene seed) at the test
frequencies (default 16..96 step 4, which holds the paper's nine frequencies of Fig. 4b), with
:func:`dptpu.models.evaluate.evaluate_dataset`. Outputs in ``DIR``: ``table.csv``, ``summary.md``
(:mod:`dptpu.experiments.study_report`) and one boxplot PNG per method (:mod:`dptpu.experiments.study_plot`).
A stopped study resumes: datasets and finished models are kept and not made again.

Torch is imported only when a model is trained.
"""
from __future__ import annotations

import hashlib
import inspect
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from dptpu.fpp.dataset import DATASET_FORMAT, list_samples, open_dataset
from dptpu.models.evaluate import evaluate_dataset
from dptpu.sim.dataset import DatasetSpec, write_dataset
from dptpu.sim.rig import load_twin_rig, parse_size

from .study_plot import write_boxplots
from .study_report import write_study_table, write_summary

__all__ = ["PAPER_SETS", "PAPER_TEST_FREQUENCIES", "TEST_GRID", "StudyOptions", "StudyRun", "StudyRow",
           "equal_step_epochs", "plan_runs", "subset_dataset", "run_study", "add_study_arguments",
           "run_study_command"]

#: The paper's training frequency sets (section "Selection of training fringe images", Fig. 4a).
PAPER_SETS: dict[str, tuple[float, ...]] = {
    "S1": (56.0,),
    "S2": (16.0, 96.0),
    "S3": (16.0, 56.0, 96.0),
    "S4": (32.0, 48.0, 64.0, 80.0),
    "S5": (16.0, 36.0, 56.0, 76.0, 96.0),
}
#: The nine "representative frequencies" the paper tests the sets on (Fig. 4b).
PAPER_TEST_FREQUENCIES: tuple[float, ...] = (16.0, 32.0, 36.0, 48.0, 56.0, 64.0, 76.0, 80.0, 96.0)
#: The issue's test grid f_h = 16..96 step 4 (it contains the paper's nine).
TEST_GRID: tuple[float, ...] = tuple(float(f) for f in range(16, 97, 4))
#: lambda1 of Eq. (15) for every run (the paper's 0.9).
LAMBDA_MSE = 0.9


@dataclass(frozen=True)
class StudyOptions:
    """What to study and at which scale (the ``dptpu model study`` flags).

    Attributes
    ----------
    out : Path
        Study folder (datasets under ``data/``, models under ``runs/``, results at the top).
    sets : tuple of str
        Names in :data:`PAPER_SETS`.
    methods : tuple of str
        Classical methods of training and test samples (``mf``, ``mw``, ``nt``); one model learns them all.
    scenes, test_scenes : int
        Random scenes of the training pool and of the held-out test set.
    size : (int, int)
        Sample size ``(width, height)`` in pixels.
    noise : tuple of float
        Camera noise levels in gray levels (the paper's 1 and 2 sigma: 1.5693, 3.1386), for training and test.
    test_frequencies : tuple of float
        High frequencies of the test set.
    steps : int
        Training steps per model wanted; raised to the next multiple that every set's epoch divides
        (:func:`equal_step_epochs`).
    batch : int
    crop : (int, int)
        Training crop ``(height, width)``.
    seed : int
        Seed of weights, crops and sample order of the set runs.
    data_seed, test_seed : int
        Scene seeds of the pool and of the test set (different: unseen scenes).
    ablation_set : str
        Set of the Fourier-loss ablation (the paper's S4).
    ablation_seeds : tuple of int
        Seeds of the ablation pairs (lambda2 = ``lambda_fourier`` vs 0); empty = no ablation.
    lambda_fourier : float
        lambda2 of Eq. (15) of the set runs (the paper's 0.1).
    threads : int
        Torch and onnxruntime threads.
    time_limit_min : float or None
        Safety stop per model (``dptpu train --time-limit-min``); a model it stops early has fewer steps than
        the others, and the summary says so.
    config : dict or None
        DP-TPU architecture (:class:`~dptpu.models.network.DPTPUConfig` keys); None = the default.
    rig : str
        Twin rig of both datasets (``nominal`` or a rig file).
    progress : bool
        One line per stage on stdout, tqdm bars (rendering, models) on stderr.
    """

    out: Path
    sets: tuple = tuple(PAPER_SETS)
    methods: tuple = ("mf", "mw", "nt")
    scenes: int = 8
    test_scenes: int = 4
    size: tuple = (160, 120)
    noise: tuple = (1.5693, 3.1386)
    test_frequencies: tuple = TEST_GRID
    steps: int = 480
    batch: int = 8
    crop: tuple = (64, 64)
    seed: int = 0
    data_seed: int = 100
    test_seed: int = 200
    ablation_set: str = "S4"
    ablation_seeds: tuple = (0,)
    lambda_fourier: float = 0.1
    threads: int = 1
    time_limit_min: float | None = None
    config: dict | None = None
    rig: str = "nominal"
    progress: bool = True

    def __post_init__(self):
        unknown = [s for s in self.sets + (self.ablation_set,) if s not in PAPER_SETS]
        if not self.sets or unknown or len(set(self.sets)) != len(self.sets):
            raise ValueError(f"--sets must list distinct names among {', '.join(PAPER_SETS)}; got "
                             f"{list(self.sets)} (ablation set {self.ablation_set!r})")
        bad = [m for m in self.methods if m not in ("mf", "mw", "nt")]
        if not self.methods or bad or len(set(self.methods)) != len(self.methods):
            raise ValueError(f"--methods must list distinct methods among mf, mw, nt; got {list(self.methods)}")
        for name in ("scenes", "test_scenes", "steps", "batch", "threads"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"--{name.replace('_', '-')} must be an integer >= 1; got {value!r}")
        if not self.test_frequencies:
            raise ValueError("--test-frequencies must list at least one frequency")
        if not self.noise:
            raise ValueError("--noise must list at least one level (gray levels)")
        if not (self.lambda_fourier > 0):
            raise ValueError(f"--lambda-fourier must be > 0 (the ablation compares it with 0); got "
                             f"{self.lambda_fourier!r}")


@dataclass(frozen=True)
class StudyRun:
    """One model of the study.

    Attributes
    ----------
    name : str
        ``S1`` .. ``S5`` for the set runs; ``S4-fourier0`` (lambda2 = 0), ``S4-seed1``, ``S4-fourier0-seed1``
        for the ablation.
    set_name : str
    frequencies : tuple of float
        High frequencies of the training samples.
    lambda_fourier : float
        lambda2 of Eq. (15).
    seed : int
    epochs : int
        Epochs over the set's samples that make the study's common number of steps.
    steps : int
        Planned optimizer steps (equal for every run of a study).
    role : {"set", "ablation"}
    """

    name: str
    set_name: str
    frequencies: tuple
    lambda_fourier: float
    seed: int
    epochs: int
    steps: int
    role: str


@dataclass(frozen=True)
class StudyRow:
    """Accuracy of one solver on one (method, frequency, noise) group of the test set."""

    run: str
    set_name: str
    lambda_fourier: float | None
    seed: int | None
    steps: int | None
    method: str
    frequency: float
    noise: float
    solver: str
    accuracy: float
    pixels: int


def equal_step_epochs(samples: dict[str, int], batch: int, steps: int) -> tuple[int, dict[str, int]]:
    """Epochs per set so that every set trains for the same number of optimizer steps.

    An epoch of a set with ``n`` samples is ``n // batch`` steps (:func:`dptpu.models.training.train`
    drops the last incomplete batch). The common step count is ``steps`` rounded up to a multiple of the
    least common multiple of those epoch lengths.

    Parameters
    ----------
    samples : dict
        Set name -> number of training samples.
    batch : int
    steps : int
        Steps wanted.

    Returns
    -------
    (int, dict)
        The common step count and set name -> epochs.

    Raises
    ------
    ValueError
        A set with fewer samples than one batch.
    """
    per_epoch = {}
    for name, count in samples.items():
        if count // batch < 1:
            raise ValueError(f"set {name}: {count} training samples are fewer than one batch of {batch}; "
                             "use more --scenes or a smaller --batch")
        per_epoch[name] = count // batch
    cycle = math.lcm(*per_epoch.values())
    total = -(-int(steps) // cycle) * cycle
    return total, {name: total // n for name, n in per_epoch.items()}


def plan_runs(options: StudyOptions, samples_per_frequency: int) -> list[StudyRun]:
    """The study's runs: one per set, then the ablation pairs, all with the same step count.

    ``samples_per_frequency`` is the pool's number of samples per high frequency (scenes x methods x noise
    levels); a set of ``k`` frequencies trains on ``k`` times that.
    """
    names = list(dict.fromkeys(options.sets + ((options.ablation_set,) if options.ablation_seeds else ())))
    total, epochs = equal_step_epochs({n: samples_per_frequency * len(PAPER_SETS[n]) for n in names},
                                      options.batch, options.steps)
    lam = float(options.lambda_fourier)
    runs = [StudyRun(n, n, PAPER_SETS[n], lam, options.seed, epochs[n], total, "set") for n in options.sets]
    ablation = options.ablation_set
    for seed in options.ablation_seeds:
        suffix = "" if seed == options.seed else f"-seed{seed}"
        if suffix or ablation not in options.sets:
            runs.append(StudyRun(f"{ablation}{suffix}", ablation, PAPER_SETS[ablation], lam, int(seed),
                                 epochs[ablation], total, "ablation"))
        runs.append(StudyRun(f"{ablation}-fourier0{suffix}", ablation, PAPER_SETS[ablation], 0.0, int(seed),
                             epochs[ablation], total, "ablation"))
    return runs


def _say(options: StudyOptions, text: str) -> None:
    if options.progress:  # through tqdm, so a progress bar on the terminal is redrawn below the line
        tqdm.write(f"[study {time.strftime('%H:%M:%S')}] {text}", file=sys.stdout)


def _render(options: StudyOptions, frequencies, scenes: int, seed: int, out: Path) -> Path:
    """A twin dataset (``dptpu sim dataset``); kept when it is already complete."""
    spec = DatasetSpec(frequencies=tuple(frequencies), methods=tuple(options.methods), scenes=scenes,
                       noise=tuple(options.noise), size=tuple(options.size), seed=seed)
    write_dataset(load_twin_rig(options.rig), spec, out, progress=options.progress)
    dataset = open_dataset(out)
    if dataset.missing:
        raise ValueError(f"{out}: {dataset.missing} samples missing after rendering")
    return out


def subset_dataset(pool: Path, frequencies, out: Path) -> int:
    """A ``dptpu-dataset/1`` folder of links to the pool samples whose high frequency is in ``frequencies``.

    Returns the number of samples linked. The folder's ``dataset.yaml`` names the pool and the frequencies.
    """
    wanted = {round(float(f), 6) for f in frequencies}
    chosen = []
    for path in list_samples(pool):
        with np.load(path, allow_pickle=False) as archive:
            if round(float(archive["frequency_high"]), 6) in wanted:
                chosen.append(path)
    if not chosen:
        raise ValueError(f"{pool}: no sample has a high frequency in {sorted(wanted)}")
    samples_dir = out / "samples"
    samples_dir.mkdir(parents=True, exist_ok=True)
    for old in samples_dir.glob("*.npz"):
        old.unlink()
    for path in chosen:
        os.symlink(os.path.relpath(path.resolve(), samples_dir.resolve()), samples_dir / path.name)
    document = {"format": DATASET_FORMAT, "subset_of": os.path.relpath(pool.resolve(), out.resolve()),
                "frequencies": sorted(wanted), "count": len(chosen)}
    (out / "dataset.yaml").write_text(yaml.safe_dump(document, sort_keys=False))
    return len(chosen)


def _train(run: StudyRun, data_dir: Path, runs_dir: Path, options: StudyOptions) -> dict:
    """Train (or resume) one model; returns its record (also written as ``runs/NAME.json``)."""
    record_path = runs_dir / f"{run.name}.json"
    onnx = runs_dir / f"{run.name}.onnx"
    if record_path.is_file() and onnx.is_file():
        return json.loads(record_path.read_text())
    import torch  # training only

    from dptpu.models.loss import LossWeights  # torch
    from dptpu.models.training import TrainOptions, train  # torch

    torch.set_num_threads(options.threads)
    checkpoint = runs_dir / f"{run.name}.ckpt"
    result = train(TrainOptions(
        data_dir=data_dir, out=onnx, epochs=run.epochs, batch=options.batch, crop=tuple(options.crop),
        seed=run.seed, model="dptpu", config=options.config, loss=LossWeights(LAMBDA_MSE, run.lambda_fourier),
        checkpoint=checkpoint, resume=checkpoint if checkpoint.is_file() else None,
        time_limit_s=None if options.time_limit_min is None else 60.0 * options.time_limit_min, progress=False))
    samples = len(list((data_dir / "samples").glob("*.npz")))
    train_s = float(sum(h["seconds"] for h in result.history))
    record = {**asdict(run), "frequencies": list(run.frequencies), "samples": samples,
              "epochs_done": result.epochs_done, "steps_done": result.epochs_done * (samples // options.batch),
              "train_s": round(train_s, 3), "parameters": result.parameters,
              "final": result.history[-1] if result.history else None}
    record_path.write_text(json.dumps(record, indent=1))
    return record


def _evaluate(run_records: list[dict], runs_dir: Path, test_dir: Path, options: StudyOptions) -> list[StudyRow]:
    """Rows of every model and of the classical solvers on the test set."""
    rows: list[StudyRow] = []
    for index, record in enumerate(run_records):
        for r in evaluate_dataset(test_dir, [runs_dir / f"{record['name']}.onnx"], threads=options.threads):
            if r.solver in ("classical", "classical+median"):
                if index == 0:
                    rows.append(StudyRow(r.solver, r.solver, None, None, None, r.method, r.frequency, r.noise,
                                         r.solver, r.accuracy, r.pixels))
                continue
            rows.append(StudyRow(record["name"], record["set_name"], record["lambda_fourier"], record["seed"],
                                 record["steps_done"], r.method, r.frequency, r.noise, "dptpu", r.accuracy,
                                 r.pixels))
    return rows


def _git_commit() -> str:
    """``HEAD`` of the checkout this package lives in, with ``+dirty`` when it has local changes."""
    root = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "*.py"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (head or "unknown") + ("+dirty" if dirty else "")


def run_study(options: StudyOptions, *, command: str | None = None) -> dict:
    """Render, train, evaluate and report the study; returns ``{"rows", "runs", "files"}``.

    Parameters
    ----------
    options : StudyOptions
    command : str, optional
        The command line, quoted in ``summary.md``.
    """
    from dptpu.models.network import DPTPUConfig  # torch

    # the code that trains: network.py is imported (and frozen for this process) with DPTPUConfig above
    commit = _git_commit()
    network_sha1 = hashlib.sha1(Path(inspect.getfile(DPTPUConfig)).read_bytes()).hexdigest()[:12]
    out = Path(options.out)
    data_dir, runs_dir = out / "data", out / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    names = list(dict.fromkeys(options.sets + ((options.ablation_set,) if options.ablation_seeds else ())))
    union = sorted({f for n in names for f in PAPER_SETS[n]})
    _say(options, f"rendering the training pool: {options.scenes} scenes at f_h {union}")
    t0 = time.perf_counter()
    pool = _render(options, union, options.scenes, options.data_seed, data_dir / "pool")
    pool_s = time.perf_counter() - t0
    _say(options, f"rendering the test set: {options.test_scenes} unseen scenes at {len(options.test_frequencies)} "
                  "frequencies")
    test_dir = _render(options, options.test_frequencies, options.test_scenes, options.test_seed, data_dir / "test")
    per_frequency = options.scenes * len(options.methods) * len(options.noise)
    runs = plan_runs(options, per_frequency)
    for name in names:
        subset_dataset(pool, PAPER_SETS[name], data_dir / name)
    records = []
    for run in tqdm(runs, desc="study", unit="model", disable=not options.progress, file=sys.stderr):
        _say(options, f"training {run.name} (f_h {list(run.frequencies)}, lambda2 {run.lambda_fourier:g}, "
                      f"seed {run.seed}): {run.epochs} epochs = {run.steps} steps")
        record = _train(run, data_dir / run.set_name, runs_dir, options)
        _say(options, f"  {run.name}: {record['steps_done']} steps in {record['train_s']:.0f} s, final loss "
                      f"{(record['final'] or {}).get('loss', float('nan')):.4f}")
        records.append(record)
    _say(options, "evaluating on the test set")
    rows = _evaluate(records, runs_dir, test_dir, options)
    context = {"command": command, "commit": commit, "network_sha1": network_sha1,
               "config": options.config or DPTPUConfig().to_dict(),
               "options": {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(options).items()
                           if k not in ("progress", "out")},
               "pool_samples": per_frequency * len(union), "pool_render_s": round(pool_s, 1),
               "samples_per_frequency": per_frequency, "total_s": round(time.perf_counter() - started, 1)}
    files = [write_study_table(rows, out / "table.csv")]
    files += write_boxplots(rows, records, out)
    files.append(write_summary(rows, records, context, out / "summary.md", plots=files[1:]))
    _say(options, "wrote " + ", ".join(str(f) for f in files))
    return {"rows": rows, "runs": records, "files": files}


# --------------------------------------------------------------------------------------------------
# Command line (registered by dptpu.cli.train_cmd as ``dptpu model study``)
# --------------------------------------------------------------------------------------------------

def _names(text: str, what: str) -> tuple[str, ...]:
    values = tuple(v.strip() for v in str(text).split(",") if v.strip())
    if not values:
        raise ValueError(f"--{what} must list at least one name; got {text!r}")
    return values


def _numbers(text: str, what: str, kind=float) -> tuple:
    """``"16,32"`` -> (16.0, 32.0); ``"16:96:4"`` -> 16, 20, ..., 96 (inclusive); ``""``/``none`` -> ()."""
    text = str(text).strip()
    if text.lower() in ("", "none"):
        return ()
    try:
        if ":" in text:
            start, stop, step = (float(v) for v in text.split(":"))
            return tuple(kind(v) for v in np.arange(start, stop + step / 2, step))
        return tuple(kind(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ValueError(f"--{what} must be comma-separated numbers or START:STOP:STEP; got {text!r}") from None


def add_study_arguments(parser) -> None:
    """The flags of ``dptpu model study`` (see :class:`StudyOptions`)."""
    parser.add_argument("--out", required=True, type=Path, metavar="DIR", help="study folder")
    parser.add_argument("--sets", default=",".join(PAPER_SETS), help="training frequency sets (default S1..S5)")
    parser.add_argument("--methods", default="mf,mw,nt", help="classical methods, one model for all (default all)")
    parser.add_argument("--scenes", type=int, default=8, help="random scenes of the training pool (default 8)")
    parser.add_argument("--test-scenes", type=int, default=4, help="unseen scenes of the test set (default 4)")
    parser.add_argument("--size", default="160x120", metavar="WIDTHxHEIGHT", help="sample size (default 160x120)")
    parser.add_argument("--noise", default="1.5693,3.1386", metavar="SIGMA,...",
                        help="noise levels in gray levels (default the paper's 1 and 2 sigma)")
    parser.add_argument("--test-frequencies", default="16:96:4", metavar="F,F,... | START:STOP:STEP",
                        help="test high frequencies (default 16:96:4, which holds the paper's nine)")
    parser.add_argument("--steps", type=int, default=480, help="training steps per model, equal for all (default 480)")
    parser.add_argument("--batch", type=int, default=8, help="samples per step (default 8)")
    parser.add_argument("--crop-size", default="64x64", metavar="WIDTHxHEIGHT", help="training crop (default 64x64)")
    parser.add_argument("--seed", type=int, default=0, help="seed of weights, crops and order (default 0)")
    parser.add_argument("--data-seed", type=int, default=100, help="scene seed of the training pool (default 100)")
    parser.add_argument("--test-seed", type=int, default=200, help="scene seed of the test set (default 200)")
    parser.add_argument("--ablation-set", default="S4", help="set of the Fourier-loss ablation (default S4)")
    parser.add_argument("--ablation-seeds", default="0", metavar="S,...",
                        help="seeds of the lambda2 = 0.1 vs 0 pairs (default 0; 'none' = no ablation)")
    parser.add_argument("--lambda-fourier", type=float, default=0.1, help="lambda2 of the set runs (default 0.1)")
    parser.add_argument("--threads", type=int, default=1, help="torch and onnxruntime threads (default 1)")
    parser.add_argument("--time-limit-min", type=float, metavar="M", help="safety stop per model, minutes")
    parser.add_argument("--config", type=json.loads, metavar="JSON", help="DP-TPU architecture (DPTPUConfig keys)")
    parser.add_argument("--rig", default="nominal", help="twin rig of both datasets (default nominal)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines or bars")


def options_from_args(args) -> StudyOptions:
    """:class:`StudyOptions` from parsed ``dptpu model study`` flags (ValueError on bad values)."""
    return StudyOptions(
        out=args.out, sets=_names(args.sets, "sets"), methods=_names(args.methods, "methods"), scenes=args.scenes,
        test_scenes=args.test_scenes, size=parse_size(args.size), noise=_numbers(args.noise, "noise"),
        test_frequencies=_numbers(args.test_frequencies, "test-frequencies"), steps=args.steps, batch=args.batch,
        crop=parse_size(args.crop_size)[::-1], seed=args.seed, data_seed=args.data_seed, test_seed=args.test_seed,
        ablation_set=args.ablation_set, ablation_seeds=_numbers(args.ablation_seeds, "ablation-seeds", int),
        lambda_fourier=args.lambda_fourier, threads=args.threads, time_limit_min=args.time_limit_min,
        config=args.config, rig=args.rig, progress=not args.quiet)


def run_study_command(args) -> int:
    """``dptpu model study``: run the study and print where the results are."""
    options = options_from_args(args)
    result = run_study(options, command=" ".join(["dptpu"] + sys.argv[1:]))
    print(f"study: {len(result['runs'])} models, {len(result['rows'])} rows -> {options.out}")
    return 0
