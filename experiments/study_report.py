"""``table.csv`` and ``summary.md`` of a frequency-set study (:mod:`dptpu.experiments.study`).

The statistics are those of the paper's Fig. 4c: for one model, method and noise level, the accuracies at
the test frequencies form a distribution; its mean, quartiles (numpy's linear interpolation) and
interquartile range say how well and how evenly the model unwraps across the frequency range.
"""
from __future__ import annotations

import csv
from collections import defaultdict
from pathlib import Path

import numpy as np

__all__ = ["TABLE_COLUMNS", "write_study_table", "accuracy_by_frequency", "distribution", "write_summary"]

TABLE_COLUMNS = ("run", "set", "lambda_fourier", "seed", "steps", "method", "frequency", "noise", "solver",
                 "accuracy", "pixels")
_PAPER_NINE = (16.0, 32.0, 36.0, 48.0, 56.0, 64.0, 76.0, 80.0, 96.0)


def _blank(value, fmt="{}"):
    return "" if value is None else fmt.format(value)


def write_study_table(rows, path) -> Path:
    """``table.csv``: one line per (run, method, frequency, noise); accuracy is a share in [0, 1]."""
    path = Path(path)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(TABLE_COLUMNS)
        for r in rows:
            writer.writerow([r.run, r.set_name, _blank(r.lambda_fourier, "{:g}"), _blank(r.seed), _blank(r.steps),
                             r.method, f"{r.frequency:g}", f"{r.noise:g}", r.solver, f"{r.accuracy:.6f}", r.pixels])
    return path


def accuracy_by_frequency(rows) -> dict:
    """``{(run, method, noise): {frequency: accuracy}}``."""
    table: dict = defaultdict(dict)
    for r in rows:
        table[(r.run, r.method, r.noise)][r.frequency] = r.accuracy
    return table


def distribution(values_by_frequency: dict, frequencies=None) -> dict:
    """Mean, quartiles, IQR, min and max (in %) of the accuracies at ``frequencies`` (default all)."""
    keys = sorted(values_by_frequency) if frequencies is None else [f for f in frequencies
                                                                    if f in values_by_frequency]
    values = 100.0 * np.array([values_by_frequency[f] for f in keys], dtype=np.float64)
    if values.size == 0:
        return {}
    q1, median, q3 = np.percentile(values, [25, 50, 75])
    return {"n": int(values.size), "mean": float(values.mean()), "q1": float(q1), "median": float(median),
            "q3": float(q3), "iqr": float(q3 - q1), "min": float(values.min()), "max": float(values.max())}


def _runs_in_order(rows, records):
    models = [r["name"] for r in records]
    return [n for n in ("classical", "classical+median") if any(r.run == n for r in rows)] + models


def _set_tables(rows, records) -> list[str]:
    table = accuracy_by_frequency(rows)
    by_name = {r["name"]: r for r in records}
    runs = [n for n in _runs_in_order(rows, records) if n not in by_name or by_name[n]["role"] == "set"]
    lines = []
    for method in sorted({r.method for r in rows}):
        for noise in sorted({r.noise for r in rows}):
            lines += [f"### {method.upper()}, noise {noise:g} gray levels", "",
                      "| run | train f_h | mean | median | Q1 - Q3 (IQR) | min | f_h = 96 | mean of the paper's nine |",
                      "|---|---|---|---|---|---|---|---|"]
            for run in runs:
                values = table.get((run, method, noise))
                if not values:
                    continue
                d, nine = distribution(values), distribution(values, _PAPER_NINE)
                trained = ", ".join(f"{f:g}" for f in by_name[run]["frequencies"]) if run in by_name else "-"
                at96 = f"{100 * values[96.0]:.2f}" if 96.0 in values else ""
                lines.append(f"| {run} | {trained} | {d['mean']:.2f} | {d['median']:.2f} | {d['q1']:.2f} - "
                             f"{d['q3']:.2f} ({d['iqr']:.2f}) | {d['min']:.2f} | {at96} | "
                             f"{nine.get('mean', float('nan')):.2f} |")
            lines.append("")
    return lines


def _frequency_tables(rows, records) -> list[str]:
    """Fig. 4b as tables: accuracy (%) per run and test frequency."""
    table = accuracy_by_frequency(rows)
    runs = _runs_in_order(rows, records)
    lines = []
    for method in sorted({r.method for r in rows}):
        for noise in sorted({r.noise for r in rows}):
            frequencies = sorted({r.frequency for r in rows if r.method == method and r.noise == noise})
            lines += [f"#### {method.upper()}, noise {noise:g}", "",
                      "| run | " + " | ".join(f"{f:g}" for f in frequencies) + " |",
                      "|---|" + "---|" * len(frequencies)]
            for run in runs:
                values = table.get((run, method, noise))
                if values:
                    lines.append(f"| {run} | " + " | ".join(f"{100 * values[f]:.1f}" if f in values else ""
                                                            for f in frequencies) + " |")
            lines.append("")
    return lines


def _cost_table(records, context) -> list[str]:
    lines = ["| run | set | lambda2 | seed | training samples | epochs | steps | train s | s / step | final loss |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in records:
        final = (r.get("final") or {}).get("loss", float("nan"))
        per_step = r["train_s"] / r["steps_done"] if r["steps_done"] else float("nan")
        lines.append(f"| {r['name']} | {r['set_name']} | {r['lambda_fourier']:g} | {r['seed']} | {r['samples']} | "
                     f"{r['epochs_done']} | {r['steps_done']} | {r['train_s']:.0f} | {per_step:.3f} | {final:.4f} |")
    steps = {r["steps_done"] for r in records}
    lines.append("")
    lines.append("Every model trained for the same number of steps." if len(steps) == 1 else
                 f"**Step counts differ ({sorted(steps)}): a model was stopped by --time-limit-min; its "
                 "comparison with the others is not at equal budget.**")
    lines.append(f"The training pool holds {context['pool_samples']} samples ({context['samples_per_frequency']} "
                 f"per high frequency), rendered in {context['pool_render_s']:.0f} s; a set of k frequencies "
                 "renders and stores k times the samples of one.")
    return lines


def _ablation_table(rows, records) -> list[str]:
    ablation = [r for r in records if r["role"] == "ablation"]
    if not ablation:
        return ["No ablation runs."]
    set_name = ablation[0]["set_name"]
    pairs = [r for r in records if r["set_name"] == set_name]
    table = accuracy_by_frequency(rows)
    groups = sorted({(r.method, r.noise) for r in rows})
    lines = ["| run | lambda2 | seed | mean of all groups | " + " | ".join(f"{m.upper()} {n:g}" for m, n in groups)
             + " | mean at f_h = 96 |", "|---|---|---|---|" + "---|" * len(groups) + "---|"]
    for r in sorted(pairs, key=lambda r: (r["seed"], -r["lambda_fourier"])):
        means = [distribution(table.get((r["name"], m, n), {})).get("mean", float("nan")) for m, n in groups]
        at96 = [100 * table[(r["name"], m, n)][96.0] for m, n in groups if 96.0 in table.get((r["name"], m, n), {})]
        lines.append(f"| {r['name']} | {r['lambda_fourier']:g} | {r['seed']} | {np.mean(means):.2f} | "
                     + " | ".join(f"{v:.2f}" for v in means) + f" | {np.mean(at96) if at96 else float('nan'):.2f} |")
    return lines


def write_summary(rows, records, context: dict, path, *, plots=()) -> Path:
    """``summary.md``: set statistics (Fig. 4c), per-frequency tables (Fig. 4b), training cost, ablation."""
    path = Path(path)
    options = context["options"]
    lines = ["# Training-frequency study (S1-S5) and Fourier-loss ablation", ""]
    if context.get("command"):
        lines += ["```", context["command"], "```", ""]
    lines += [f"- code: git {context['commit']} (network.py sha1 {context.get('network_sha1', '?')}); DP-TPU "
              f"config {context['config']}",
              f"- training pool: {options['scenes']} scenes (seed {options['data_seed']}), methods "
              f"{', '.join(options['methods'])}, noise {', '.join(f'{v:g}' for v in options['noise'])} gray levels, "
              f"{options['size'][0]}x{options['size'][1]}"
              f" px; test set: {options['test_scenes']} unseen scenes (seed {options['test_seed']}) at f_h "
              f"{', '.join(f'{f:g}' for f in options['test_frequencies'])}",
              f"- training: batch {options['batch']}, crop {options['crop'][0]}x{options['crop'][1]}, "
              f"{options['threads']} thread(s), AdamW lr 1e-3, loss 0.9 MSE + lambda2 Fourier (Eqs. 15-17)",
              f"- whole study: {context['total_s']:.0f} s", "",
              "Accuracy = % of valid pixels with the exact fringe order. Statistics over the test frequencies.", ""]
    lines += ["## Accuracy distribution per set (Fig. 4c)", ""] + _set_tables(rows, records)
    if plots:
        lines += ["Boxplots: " + ", ".join(f"`{Path(p).name}`" for p in plots), ""]
    lines += ["## Training cost", ""] + _cost_table(records, context) + [""]
    lines += ["## Fourier-loss ablation", ""] + _ablation_table(rows, records) + [""]
    lines += ["## Accuracy per test frequency (Fig. 4b)", ""] + _frequency_tables(rows, records)
    path.write_text("\n".join(lines))
    return path
