"""``dptpu bench fpp``: the report's structure and that each pair (ours, reference) gives the same numbers.

Timings are never asserted; a tiny 96x64 scene and one repeat keep this fast.
"""
from __future__ import annotations

import contextlib
import io
import json
import sys

import pytest

from dptpu.cli import bench_cmd
from dptpu.cli.main import main

SMALL = ["--size", "96x64", "--repeats", "1"]


@pytest.fixture(scope="module")
def report():
    """The JSON report of one small run (96x64 camera, 1 repeat), with its exit code."""
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main(["bench", "fpp", "--json", *SMALL])
    return code, json.loads(buffer.getvalue())


def _timing(entry):
    assert set(entry) == {"best_ms", "median_ms"}
    assert 0 < entry["best_ms"] <= entry["median_ms"]


def test_bench_fpp_json_has_the_three_sections_and_exits_0(report):
    code, data = report
    assert code == 0  # 0 means every pair agreed (1 would mean one did not)
    assert {"phase", "unwrap", "triangulate"} <= set(data)
    assert data["size"] == [96, 64]
    assert data["repeats"] == 1
    assert data["machine"]["cores"] >= 1


def test_bench_fpp_phase_matches_opencv_psp_on_the_same_frames(report):
    phase = report[1]["phase"]
    assert phase["frames"] == 24 and phase["steps"] == 12
    for key in ("ours_24_frames", "opencv_24_frames", "ours_3_frame_sets"):
        _timing(phase[key])
    assert phase["ratio_24_frames"] == pytest.approx(
        phase["opencv_24_frames"]["best_ms"] / phase["ours_24_frames"]["best_ms"])
    assert phase["opencv_per_set_ms"] == pytest.approx(phase["opencv_24_frames"]["best_ms"] / 8)
    agreement = phase["agreement"]
    # Same 3-frame sets, same convention: measured 0.0185 rad rms (OpenCV's band-pass filter); a sign,
    # offset or frame-order slip would give ~1.8 rad.
    assert agreement["agree"] is True
    assert agreement["same_sets_rms_rad"] < 0.05
    assert agreement["vs_12_step_rms_rad"] < 0.05
    # Against the true phase: ours 12-step 0.0031 rad, 3-frame 0.0062 rad (measured; noise 0.5 DN, B ~ 80 DN).
    truth = agreement["rms_vs_truth_rad"]
    assert truth["ours_12_step"] < 0.01
    assert truth["ours_12_step"] < truth["ours_3_frame_sets"] < 0.02


@pytest.mark.parametrize("method, f_l", [("mf", 1.0), ("mw", 47.0), ("nt", 10.9)])
def test_bench_fpp_unwrap_orders_equal_the_bare_equation(report, method, f_l):
    entry = report[1]["unwrap"][method]
    _timing(entry["ours"])
    _timing(entry["reference"])
    assert entry["f_h"] == 48.0 and entry["f_l"] == f_l
    assert entry["orders_differ"] == 0
    assert entry["agree"] is True
    # at 0.5 DN of noise every method is exact; NT too since it matches the nearest key of the pair table
    # (fpp.tpu.unwrap_nt; the old integer-rounded key rejected 3.9 % of these pixels)
    assert entry["ours_invalid"] == 0
    assert entry["correct_fraction"] == 1.0


def test_bench_fpp_triangulation_equals_the_per_pixel_solve(report):
    tri = report[1]["triangulate"]
    for key in ("precompute", "ours", "reference_subset", "reference_full_scaled"):
        _timing(tri[key])
    assert tri["pixels"] == 96 * 64
    assert tri["subset_pixels"] == 2000
    assert tri["reference_full_scaled"]["best_ms"] == pytest.approx(
        tri["reference_subset"]["best_ms"] * 96 * 64 / 2000)
    assert tri["max_difference_mm"] < 1e-6
    assert tri["agree"] is True
    assert tri["rms_error_vs_scene_mm"] < 0.1  # measured 0.032 mm at ~1 m


def test_bench_fpp_table_names_each_reference(capsys):
    assert main(["bench", "fpp", *SMALL]) == 0
    out = capsys.readouterr().out
    for text in ("OpenCV PSP computePhaseMap", "reference nt", "triangulate_reference", "8 disjoint 3-frame sets"):
        assert text in out
    assert out.count("AGREE") == 5 and "DISAGREE" not in out


@pytest.mark.parametrize("argv, message", [
    (["--size", "640by480"], "size must be WIDTHxHEIGHT"),
    (["--size", "64x48"], "at least 96x64"),
    (["--size", "96x64", "--repeats", "0"], "repeats must be an integer >= 1; got 0"),
])
def test_bench_fpp_bad_options_exit_2_with_a_message(capsys, argv, message):
    assert main(["bench", "fpp", *argv]) == 2
    assert message in capsys.readouterr().err


def test_bench_fpp_without_the_source_tree_says_where_it_looked(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr(bench_cmd, "benchmarks_dir", lambda: tmp_path / "benchmarks")
    monkeypatch.delitem(sys.modules, bench_cmd.MODULE_NAME, raising=False)
    assert main(["bench", "fpp", *SMALL]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "benchmarks" / "fpp_bench.py") in err
    assert "source checkout" in err
