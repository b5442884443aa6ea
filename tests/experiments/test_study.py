"""The training-frequency study (``dptpu model study``): set definitions, equal step budgets, a tiny run end to end."""
import csv
import json
from collections import defaultdict

import cv2
import numpy as np
import pytest

from dptpu.cli.main import main
from dptpu.experiments.study import (
    PAPER_SETS,
    PAPER_TEST_FREQUENCIES,
    TEST_GRID,
    StudyOptions,
    equal_step_epochs,
    plan_runs,
    subset_dataset,
)
from dptpu.experiments.study_report import distribution

#: A tiny DP-TPU (a few thousand parameters; keys every architecture version accepts).
TINY = {"widths": [8, 8, 8, 8], "depths": [1, 1, 1, 1], "heads": [1, 1, 1, 2], "decoder_width": 8}
TEST_F = (16.0, 56.0, 96.0)


def test_sets_are_the_papers():
    # section "Selection of training fringe images": S1 = {56}, S2 = {16, 96}, S3 = {16, 56, 96},
    # S4 = {32, 48, 64, 80}, S5 = {16, 36, 56, 76, 96}; nine test frequencies (Fig. 4b)
    assert PAPER_SETS == {"S1": (56,), "S2": (16, 96), "S3": (16, 56, 96), "S4": (32, 48, 64, 80),
                          "S5": (16, 36, 56, 76, 96)}
    assert PAPER_TEST_FREQUENCIES == (16, 32, 36, 48, 56, 64, 76, 80, 96)
    assert TEST_GRID == tuple(range(16, 97, 4)) and set(PAPER_TEST_FREQUENCIES) <= set(TEST_GRID)
    # the union of the sets is the paper's nine
    assert sorted({f for fs in PAPER_SETS.values() for f in fs}) == list(PAPER_TEST_FREQUENCIES)


def test_equal_step_epochs_gives_every_set_the_same_steps():
    samples = {name: 32 * len(fs) for name, fs in PAPER_SETS.items()}  # 8 scenes x 2 methods x 2 noise levels
    total, epochs = equal_step_epochs(samples, batch=8, steps=480)
    assert total == 480 and epochs == {"S1": 120, "S2": 60, "S3": 40, "S4": 30, "S5": 24}
    assert {e * (samples[n] // 8) for n, e in epochs.items()} == {480}
    total, epochs = equal_step_epochs(samples, batch=8, steps=100)  # rounded up to lcm(4, 8, 12, 16, 20) = 240
    assert total == 240 and epochs["S1"] == 60 and epochs["S5"] == 12
    with pytest.raises(ValueError, match="S1: 3 training samples are fewer than one batch of 4"):
        equal_step_epochs({"S1": 3}, batch=4, steps=10)


def test_ablation_runs_differ_only_in_lambda2(tmp_path):
    options = StudyOptions(out=tmp_path, sets=("S1", "S4"), methods=("mf",), ablation_seeds=(0, 1), steps=100)
    runs = {r.name: r for r in plan_runs(options, samples_per_frequency=16)}
    assert list(runs) == ["S1", "S4", "S4-fourier0", "S4-seed1", "S4-fourier0-seed1"]
    assert {r.steps for r in runs.values()} == {104}  # lcm(2, 8) = 8 -> 104 >= 100
    for seed_suffix in ("", "-seed1"):
        on, off = runs[f"S4{seed_suffix}"], runs[f"S4-fourier0{seed_suffix}"]
        assert (on.lambda_fourier, off.lambda_fourier) == (0.1, 0.0)
        assert {k: v for k, v in vars(on).items() if k not in ("name", "lambda_fourier", "role")} == \
            {k: v for k, v in vars(off).items() if k not in ("name", "lambda_fourier", "role")}


def test_bad_options_name_the_flag(tmp_path, capsys):
    with pytest.raises(ValueError, match="--sets must list distinct names among S1, S2, S3, S4, S5"):
        StudyOptions(out=tmp_path, sets=("S9",))
    assert main(["model", "study", "--out", str(tmp_path), "--methods", "xx"]) == 2
    assert "--methods must list distinct methods" in capsys.readouterr().err


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory):
    """S1 and S2 (+ the S2 ablation pair), MF only, one 96x64 scene, 8 steps of batch 1, via the CLI."""
    out = tmp_path_factory.mktemp("study") / "study"
    code = main(["model", "study", "--out", str(out), "--sets", "S1,S2", "--methods", "mf", "--scenes", "1",
                 "--test-scenes", "1", "--size", "96x64", "--noise", "1.5693", "--test-frequencies", "16,56,96",
                 "--steps", "8", "--batch", "1", "--crop-size", "64x64", "--ablation-set", "S2",
                 "--ablation-seeds", "0", "--config", json.dumps(TINY), "--quiet"])
    assert code == 0
    with (out / "table.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    return out, rows


def test_tiny_study_writes_the_table(tiny_study):
    _out, rows = tiny_study
    assert list(rows[0]) == ["run", "set", "lambda_fourier", "seed", "steps", "method", "frequency", "noise",
                             "solver", "accuracy", "pixels"]
    by_run = defaultdict(list)
    for r in rows:
        by_run[r["run"]].append(r)
    assert sorted(by_run) == ["S1", "S2", "S2-fourier0", "classical", "classical+median"]
    for run, group in by_run.items():  # one row per test frequency, all MF at the one noise level
        assert sorted(float(r["frequency"]) for r in group) == list(TEST_F), run
        assert {(r["method"], r["noise"]) for r in group} == {("mf", "1.5693")}
        assert all(0.0 <= float(r["accuracy"]) <= 1.0 for r in group)
    pixels = {(r["frequency"], r["run"]): int(r["pixels"]) for r in rows}
    for f in ("16", "56", "96"):  # every solver is scored on the same valid pixels
        assert len({p for (g, _), p in pixels.items() if g == f}) == 1 and pixels[(f, "S1")] > 1000
    assert {r["solver"] for r in by_run["S1"]} == {"dptpu"} and by_run["S1"][0]["set"] == "S1"


def test_tiny_study_trains_every_model_for_equal_steps(tiny_study):
    out, rows = tiny_study
    records = {p.stem: json.loads(p.read_text()) for p in (out / "runs").glob("*.json")}
    assert sorted(records) == ["S1", "S2", "S2-fourier0"]
    # S1 has 1 sample (8 epochs of 1 step), S2 2 samples (4 epochs of 2 steps)
    assert {n: (r["samples"], r["epochs_done"], r["steps_done"]) for n, r in records.items()} == \
        {"S1": (1, 8, 8), "S2": (2, 4, 8), "S2-fourier0": (2, 4, 8)}
    assert {r["steps"] for r in rows if r["solver"] == "dptpu"} == {"8"}
    assert "Every model trained for the same number of steps." in (out / "summary.md").read_text()


def test_tiny_study_subsets_hold_only_their_frequencies(tiny_study):
    out, _ = tiny_study
    from dptpu.fpp.dataset import list_samples, read_sample

    for name in ("S1", "S2"):
        samples = [read_sample(p) for p in list_samples(out / "data" / name)]
        assert sorted(s.frequency_high for s in samples) == sorted(PAPER_SETS[name])
        assert {s.frequency_low for s in samples} == {1.0}  # MF: f_l = 1
        assert {s.scene_seed for s in samples} == {read_sample(list_samples(out / "data" / "pool")[0]).scene_seed}
    with pytest.raises(ValueError, match=r"no sample has a high frequency in \[48.0\]"):
        subset_dataset(out / "data" / "pool", [48], out / "data" / "none")


def test_tiny_study_ablation_rows_differ_only_in_lambda2(tiny_study):
    _, rows = tiny_study

    def keyed(run):
        return {(r["method"], r["frequency"], r["noise"]): r for r in rows if r["run"] == run}

    on, off = keyed("S2"), keyed("S2-fourier0")
    assert on.keys() == off.keys() and len(on) == 3
    for key in on:
        assert (on[key]["lambda_fourier"], off[key]["lambda_fourier"]) == ("0.1", "0")
        for column in ("set", "seed", "steps", "solver", "pixels"):
            assert on[key][column] == off[key][column]


def test_tiny_study_boxplot_is_a_png(tiny_study):
    out, _ = tiny_study
    image = cv2.imread(str(out / "boxplot-mf.png"))
    assert image is not None and image.ndim == 3 and image.shape[0] > 300
    # the "Tra" box is drawn in its red (BGR 60, 60, 200), the set boxes in blue (200, 140, 60)
    assert np.any(np.all(image == (60, 60, 200), axis=-1)) and np.any(np.all(image == (200, 140, 60), axis=-1))


def test_distribution_quartiles():
    stats = distribution({16.0: 1.0, 56.0: 0.9, 96.0: 0.8, 36.0: 0.7})
    assert stats["n"] == 4 and stats["mean"] == pytest.approx(85.0) and stats["median"] == pytest.approx(85.0)
    assert stats["q1"] == pytest.approx(77.5) and stats["q3"] == pytest.approx(92.5) and stats["iqr"] == \
        pytest.approx(15.0) and stats["min"] == pytest.approx(70.0)
    assert distribution({16.0: 1.0, 56.0: 0.5}, frequencies=[56.0])["mean"] == pytest.approx(50.0)
