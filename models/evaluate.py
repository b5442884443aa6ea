"""Fringe-order accuracy of solvers on a held-out dataset, per method, frequency and noise (no torch).

Solvers side by side: ``classical`` (the dataset's coarse order: Eq. (5), (7) or (9)), ``classical+median``
(3x3 median filter of the classical order over valid pixels, the cheap fix users try first), and every
ONNX model given (``dptpu`` / ``unet`` by their metadata kind, or the file stem if two share a kind), on
the methods it serves (:meth:`FringeOrderModel.serves`). A DP-TPU model's rounded order is post-processed
by the neighbour consensus of :mod:`dptpu.models.consensus` (as ``dptpu unwrap`` does) unless
``consensus=False``; the U-Net baseline's is not (the vote uses the classical order, a physics prior). NT
reaches a DP-TPU model in the MF representation of :mod:`dptpu.models.nt_prior`
(:func:`dptpu.models.refine.refine_order`). ``vote_baseline=True`` adds the solver ``classical+vote``: the
same consensus vote on the order of DP-TPU's prior alone (:func:`dptpu.models.refine.network_prior`: NT's
band prior, MF and MW's order read at the projector's ends), what the post-processing does without a network.

Accuracy = share of valid pixels whose fringe order equals the label exactly.
"""
from __future__ import annotations

import csv
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from dptpu.fpp.dataset import list_samples, read_sample

from .consensus import consensus_order
from .inference import FringeOrderModel
from .refine import network_prior, refine_order

__all__ = ["Row", "evaluate_dataset", "format_summary", "median_order", "solver_names", "write_table"]


@dataclass(frozen=True)
class Row:
    """Accuracy of one solver on the samples of one (method, frequency, noise) group."""

    method: str
    frequency: float
    noise: float
    solver: str
    accuracy: float
    pixels: int


def median_order(order: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """3x3 median of an integer order map, ``(H, W)`` int32; invalid pixels keep their value.

    Invalid neighbours are replaced by the pixel's own order before filtering (so they do not pull it).
    """
    order = np.asarray(order, dtype=np.float64)
    filled = np.where(valid, order, np.nan)
    stack = np.stack([np.roll(np.roll(np.pad(filled, 1, mode="edge"), dy, 0), dx, 1)[1:-1, 1:-1]
                      for dy in (-1, 0, 1) for dx in (-1, 0, 1)])  # (9, H, W)
    stack = np.where(np.isnan(stack), order[None], stack)
    return np.where(valid, np.rint(np.median(stack, axis=0)), order).astype(np.int32)


def solver_names(models) -> list[str]:
    """Solver name of each loaded model: its metadata kind (``dptpu``, ``unet``), or the file stem if two share one."""
    kinds = [m.kind for m in models]
    return [k if kinds.count(k) == 1 else Path(m.path).stem for k, m in zip(kinds, models)]


def evaluate_dataset(data_dir, models=(), *, threads: int | None = None, consensus: bool = True,
                     vote_baseline: bool = False, progress: bool = False) -> list[Row]:
    """Accuracy rows for every (method, frequency, noise) group of ``data_dir`` and every solver.

    ``models`` are ONNX paths or already loaded :class:`FringeOrderModel` objects; a model runs only on the
    methods of its training set (:attr:`FringeOrderModel.trained_methods`): no row for the others.
    ``consensus``: post-process the models' orders (:func:`dptpu.models.consensus.consensus_order`);
    ``vote_baseline``: add the solver ``classical+vote`` (module docstring); ``progress``: a tqdm bar on stderr.
    """
    loaded = [m if isinstance(m, FringeOrderModel) else FringeOrderModel.load(m, threads=threads) for m in models]
    names = solver_names(loaded)
    correct: dict = defaultdict(int)
    pixels: dict = defaultdict(int)
    for path in tqdm(list_samples(data_dir), desc="evaluating", unit="sample", disable=not progress, file=sys.stderr):
        sample = read_sample(path)
        valid = sample.valid
        n_valid = int(valid.sum())
        if n_valid == 0:
            continue
        group = (sample.method, round(sample.frequency_high, 6), round(sample.noise_sigma, 6))
        label = sample.label_order.astype(np.int32)
        coarse = np.rint(sample.coarse_order).astype(np.int32)
        solvers = {"classical": coarse, "classical+median": median_order(coarse, valid)}
        if vote_baseline:
            _, start = network_prior(sample.method, sample.wrapped_high, sample.wrapped_low, coarse,
                                     sample.frequency_high, sample.frequency_low, valid)
            solvers["classical+vote"] = consensus_order(start, start, sample.wrapped_high, valid)
        for name, model in zip(names, loaded):
            if not model.serves(sample.method):
                continue  # the model was not trained for this method (no row, a blank in the summary)
            solvers[name] = refine_order(model, sample.method, sample.wrapped_high, sample.wrapped_low, coarse,
                                         sample.frequency_high, sample.frequency_low, valid,
                                         consensus=consensus and model.kind == "dptpu")
        for name, order in solvers.items():
            correct[group + (name,)] += int(np.count_nonzero((order == label) & valid))
            pixels[group + (name,)] += n_valid
    return [Row(method=k[0], frequency=k[1], noise=k[2], solver=k[3], accuracy=correct[k] / pixels[k],
                pixels=pixels[k]) for k in sorted(pixels)]


def write_table(rows: list[Row], path) -> Path:
    """``table.csv`` with columns method, frequency, noise, solver, accuracy, pixels."""
    path = Path(path)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["method", "frequency", "noise", "solver", "accuracy", "pixels"])
        for r in rows:
            writer.writerow([r.method, f"{r.frequency:g}", f"{r.noise:g}", r.solver, f"{r.accuracy:.6f}", r.pixels])
    return path


def format_summary(rows: list[Row]) -> str:
    """A Markdown table: one line per (method, frequency, noise), one column per solver (accuracy in %)."""
    solvers = list(dict.fromkeys(r.solver for r in rows))
    groups: dict = defaultdict(dict)
    for r in rows:
        groups[(r.method, r.frequency, r.noise)][r.solver] = r.accuracy
    lines = ["| method | f_h | noise | " + " | ".join(solvers) + " |",
             "|---|---|---|" + "---|" * len(solvers)]
    for (method, frequency, noise), values in sorted(groups.items()):
        cells = [f"{100 * values[s]:.2f}" if s in values else "" for s in solvers]
        lines.append(f"| {method} | {frequency:g} | {noise:g} | " + " | ".join(cells) + " |")
    common = [v for v in groups.values() if all(s in v for s in solvers)]  # groups every solver ran on
    if common:
        means = [np.mean([v[s] for v in common]) for s in solvers]
        lines.append(f"| mean of {len(common)} groups with every solver | | | "
                     + " | ".join(f"{100 * m:.2f}" for m in means) + " |")
    return "\n".join(lines) + "\n"
