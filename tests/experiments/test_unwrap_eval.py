"""dptpu.experiments.unwrap_eval: the unseen-rig evaluation (issue #5 item 7) on a tiny test set.

The set: the paper's dynamic rig at 160x120, one random scene of seed root 300, f_h = 16, 56, 96, MF/MW/NT,
1 and 2 sigma. Measured on it (commit of this test): classical at f_h = 16, 1 sigma: MF 99.3 %, MW 98.6 %,
NT 98.2 %; at f_h = 96, 1 sigma the 3x3 median lifts MF from 56.8 % to 74.7 % and MW from 42.4 % to 65.5 %
(at 160x120 the fringes of f_h = 96 are about 2 camera pixels wide).
"""
from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest

from dptpu.experiments.unwrap_eval import (
    DEFAULT_SEED,
    UnwrapEvalSpec,
    error_ratio,
    goal_checks,
    make_test_set,
    run_unwrap_eval,
    spec_from_dataset,
)
from dptpu.experiments.unwrap_eval_plots import error_plot_size, heatmap_size
from dptpu.fpp.dataset import list_samples, read_sample
from dptpu.models.evaluate import Row
from dptpu.models.inference import FringeOrderModel, shipped_model_path

FREQUENCIES = (16.0, 56.0, 96.0)
NOISE = (1.5693, 3.1386)
SPEC = UnwrapEvalSpec(frequencies=FREQUENCIES, noise=NOISE, scenes=1, size=(160, 120))


@pytest.fixture(scope="module")
def models():
    path = shipped_model_path()
    return [FringeOrderModel.load(path, threads=1)] if path is not None else []


@pytest.fixture(scope="module")
def evaluation(tmp_path_factory, models):
    out = tmp_path_factory.mktemp("unwrap_eval")
    return run_unwrap_eval(SPEC, out, models=models), out


def _accuracy(rows, method, frequency, noise, solver):
    (row,) = [r for r in rows if (r.method, r.frequency, r.noise, r.solver) == (method, frequency, noise, solver)]
    return row.accuracy


def test_test_set_is_the_unseen_rig_with_unseen_scenes(evaluation):
    result, _ = evaluation
    spec = spec_from_dataset(result.data_dir)
    assert spec.seed == DEFAULT_SEED == 300  # the shipped model saw 100 (training) and 200 (held out)
    assert spec.frequencies == FREQUENCIES and spec.noise == NOISE and spec.methods == ("mf", "mw", "nt")
    from dptpu.fpp.calibration import load_rig

    rig = load_rig(result.data_dir / "rig.yaml")
    assert rig.projector.size == (1024, 768) and rig.camera.size == (160, 120)
    samples = list_samples(result.data_dir)
    assert len(samples) == 3 * 3 * 2
    nt = [read_sample(p) for p in samples if read_sample(p).method == "nt"]
    assert {s.frequency_low for s in nt} == {10.9}


def test_table_has_the_columns_and_one_row_per_group_and_solver(evaluation, models):
    _, out = evaluation
    with (out / "table.csv").open() as handle:
        table = list(csv.reader(handle))
    assert table[0] == ["method", "frequency", "noise", "solver", "accuracy", "pixels"]
    model_groups = sum(len([m for m in ("mf", "mw", "nt") if model.serves(m)]) for model in models)
    assert len(table) - 1 == len(FREQUENCIES) * len(NOISE) * (2 * 3 + model_groups)
    assert all(0.0 <= float(r[4]) <= 1.0 and int(r[5]) > 5000 for r in table[1:])


def test_classical_is_right_at_low_frequency_and_the_median_helps_at_high(evaluation):
    rows = evaluation[0].rows
    for method in ("mf", "mw", "nt"):
        assert _accuracy(rows, method, 16.0, NOISE[0], "classical") > 0.97  # measured 98.2-99.3 %
    for method in ("mf", "mw"):
        classical = _accuracy(rows, method, 96.0, NOISE[0], "classical")
        assert classical < 0.7  # measured 56.8 / 42.4 %: the hard end of the range
        assert _accuracy(rows, method, 96.0, NOISE[0], "classical+median") > classical + 0.1  # measured +18 / +23


def test_nt_reaches_the_network_through_its_band_prior_and_beats_the_classical_lookup(evaluation, models):
    if not models or not models[0].serves("nt"):
        pytest.skip("needs a shipped DP-TPU model that serves NT")
    result, out = evaluation
    for noise in NOISE:  # f_h = 56: at 160x120 the fringes of f_h = 96 are 2 px wide, outside the network's range
        classical = _accuracy(result.rows, "nt", 56.0, noise, "classical")
        dptpu = _accuracy(result.rows, "nt", 56.0, noise, models[0].kind)
        assert classical < 0.8  # measured 75.2 % / 51.8 %: one pixel's key cannot tell the pairs apart
        assert dptpu > 0.98  # measured 99.70 % / 99.65 %
    if "nt" not in models[0].trained_methods:
        assert "NT through its band prior in the MF representation" in (out / "summary.md").read_text()


def test_figures_decode_with_their_layout_size(evaluation, models):
    _, out = evaluation
    heatmap = cv2.imread(str(out / "heatmap.png"))
    assert heatmap.shape[:2][::-1] == heatmap_size(len(FREQUENCIES), 3 * len(NOISE), 2 + len(models))
    errors = cv2.imread(str(out / "error_vs_frequency.png"))
    assert errors.shape[:2][::-1] == error_plot_size(3, len(NOISE))
    assert errors.std() > 10  # drawn, not blank


def test_summary_states_goals_with_pass_or_fail(evaluation, models):
    summary = (evaluation[1] / "summary.md").read_text()
    assert "| method | f_h | noise | classical | classical+median" in summary
    if models:
        assert summary.count("FAIL") + summary.count("PASS") == 3
        assert "Error rate of `dptpu` over classical, f_h >= 64" in summary


def _rows(accuracies, solver, pixels=1000):
    return [Row(method=m, frequency=f, noise=n, solver=solver, accuracy=a, pixels=pixels)
            for (m, f, n), a in accuracies.items()]


def test_error_ratio_pools_pixels_of_high_frequencies():
    classical = {("mf", 48.0, 1.0): 0.5, ("mf", 64.0, 1.0): 0.8, ("mf", 96.0, 1.0): 0.6}
    model = {("mf", 48.0, 1.0): 0.9, ("mf", 64.0, 1.0): 0.98, ("mf", 96.0, 1.0): 0.94}
    rows = _rows(classical, "classical") + _rows(model, "dptpu")
    c_rate, s_rate, ratio = error_ratio(rows, "dptpu")[("mf", 1.0)]
    assert c_rate == pytest.approx(0.3) and s_rate == pytest.approx(0.04)  # (0.2 + 0.4) / 2, (0.02 + 0.06) / 2
    assert ratio == pytest.approx(0.04 / 0.3)


def test_goal_checks_pass_and_fail_at_the_thresholds():
    freqs = (16.0, 96.0)
    classical = {(m, f, n): 0.5 for m in ("mf", "mw", "nt") for f in freqs for n in (1.0, 2.0)}
    good = {(m, f, n): (0.99 if n == 1.0 else 0.97) if f == 16.0 else (0.995 if n == 1.0 else 0.975)
            for m in ("mf", "mw", "nt") for f in freqs for n in (1.0, 2.0)}
    rows = _rows(classical, "classical") + _rows(good, "dptpu")
    assert [passed for _, passed, _ in goal_checks(rows, "dptpu")] == [True, True, True]
    worse = {**good, ("mw", 96.0, 2.0): 0.9}  # 2 sigma below 97 %, and error 10 % vs 50 %: ratio 0.2
    rows = _rows(classical, "classical") + _rows(worse, "dptpu")
    checks = goal_checks(rows, "dptpu")
    assert [passed for _, passed, _ in checks] == [True, False, True]
    assert "lowest 90.00 % (MW f_h = 96)" in checks[1][2]
    no_nt = {k: v for k, v in good.items() if k[0] != "nt"}
    checks = goal_checks(_rows(classical, "classical") + _rows(no_nt, "dptpu"), "dptpu")
    assert not any(passed for _, passed, _ in checks) and "not run on NT" in checks[0][2]


def test_bad_renderer_and_options_raise_value_errors(tmp_path):
    with pytest.raises(ValueError, match="--renderer must be one of raycast, blender"):
        UnwrapEvalSpec(renderer="mitsuba")
    with pytest.raises(ValueError, match="--scenes must be >= 1"):
        make_test_set(UnwrapEvalSpec(scenes=0, size=(160, 120)), tmp_path / "set")
    with pytest.raises(ValueError, match="ambiguous NT pair"):
        make_test_set(UnwrapEvalSpec(frequencies=(21.8,), size=(160, 120)), tmp_path / "set")


def test_blender_rendered_test_set(tmp_path):
    from dptpu.sim.blender import BlenderNotInstalledError, blender_python

    try:
        blender_python()
    except BlenderNotInstalledError as exc:
        pytest.skip(f"Blender environment missing ({exc})")
    spec = UnwrapEvalSpec(frequencies=(16.0,), noise=(1.5693,), scenes=1, size=(160, 120), renderer="blender",
                          methods=("mf",), blender_samples=4)
    result = run_unwrap_eval(spec, tmp_path / "out")
    assert spec_from_dataset(result.data_dir).renderer == "blender"
    (sample,) = [read_sample(p) for p in list_samples(result.data_dir)]
    assert sample.valid.sum() > 0.5 * sample.valid.size  # measured 76 % of 160x120
    # measured 97.3 % (Cycles at 4 samples per pixel adds its own noise to the 1 sigma camera noise)
    assert _accuracy(result.rows, "mf", 16.0, 1.5693, "classical") > 0.95
    assert np.isfinite([r.accuracy for r in result.rows]).all()
