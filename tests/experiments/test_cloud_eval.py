"""``dptpu eval cloud``'s scoring (dptpu.experiments.cloud_eval) on one tiny twin scene of a rig outside training."""
from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from dptpu.experiments.cloud_eval import (
    OUTSIDE_RIGS,
    CloudEvalSpec,
    pool_rows,
    published_cloud,
    render_eval_captures,
    run_cloud_eval,
    score_capture,
)
from dptpu.fpp.calibration import load_rig
from dptpu.fpp.capture import read_capture
from dptpu.fpp.cloud_accuracy import order_shift
from dptpu.fpp.reconstruct import unwrap_capture
from dptpu.models.inference import FringeOrderModel, shipped_model_path
from dptpu.models.refine import refine_capture_result


def _spec(**changes) -> CloudEvalSpec:
    base = {"steps": (12,), "noise_sigmas": (0.0,), "methods": ("mf", "nt")}
    return CloudEvalSpec(**{**base, **changes})


def test_without_mixed_pixels_or_noise_every_published_point_is_right(tmp_path):
    # one ray per pixel, 12 noiseless steps: every order is right and every point lies on the true surface
    raw = _spec(supersample=1, min_confidence=0.0, edges=False)
    capture, = render_eval_captures(raw, tmp_path)
    rows = score_capture(capture, raw)
    assert [(r["method"], r["solver"]) for r in rows] == [("mf", "classical"), ("nt", "classical")]
    for row in rows:
        assert row["wrong"] == 0 and row["wrong_share"] == 0.0, row
        assert row["published"] > 0.5 * 96 * 72 and row["completeness"] > 0.9, row  # measured 96.7 %
        assert row["published_truly_valid"] <= row["published"], row
        assert row["dropped_low_confidence"] == row["dropped_at_edges"] == 0, row
    # the confidence and depth-edge filters only take points away: still none wrong
    for row, filtered in zip(rows, score_capture(capture, _spec(supersample=1)), strict=True):
        assert filtered["wrong"] == 0 and filtered["published"] <= row["published"], filtered
        assert row["published"] - filtered["published"] == filtered["dropped_low_confidence"] \
            + filtered["dropped_at_edges"] + filtered["dropped_on_islands"], filtered


def test_mixed_pixels_at_depth_edges_make_points_off_the_surface(tmp_path):
    # 3x3 supersampling: pixels straddling a depth edge blend two phases (flying points or wrong orders)
    raw = _spec(methods=("mf",), min_confidence=0.0, edges=False)
    capture, = render_eval_captures(raw, tmp_path)
    row, = score_capture(capture, raw)
    assert row["off_surface"] > 0 and row["wrong"] == row["wrong_order"] + row["off_surface"], row
    assert row["wrong_share"] < 0.2, row  # the edges are a band, not the surface (measured 5.9 % at 96x72)
    filtered, = score_capture(capture, _spec(methods=("mf",)))  # dptpu triangulate's filters take most of them
    assert filtered["dropped_at_edges"] > 0 and filtered["wrong"] < row["wrong"], filtered


def test_run_writes_the_table_and_json_and_pools_counts_exactly(tmp_path):
    model_path = shipped_model_path()
    if model_path is None:
        pytest.skip("no shipped DP-TPU model")
    model = FringeOrderModel.load(model_path)
    spec = _spec(steps=(12, 3), noise_sigmas=(0.0, 2.0), methods=("mf",))
    result = run_cloud_eval(spec, tmp_path, models=[model], command="dptpu eval cloud")
    assert len(result.rows) == 4 * 2  # (12, 3 steps) x (0, 2 sigma) x (classical, dptpu)
    assert {r["solver"] for r in result.rows} == {"classical", "dptpu"} and {r["rig"] for r in result.rows} \
        == {OUTSIDE_RIGS[0].name}
    assert result.pooled == pool_rows(result.rows)
    for entry in result.pooled:
        rows = [r for r in result.rows if (r["steps"], r["noise_sigma"], r["solver"])
                == (entry["steps"], entry["noise_sigma"], entry["solver"])]
        assert entry["wrong"] == sum(r["wrong"] for r in rows)
        assert entry["wrong_share"] == pytest.approx(entry["wrong"] / entry["published"])
    table = result.files["table"].read_text()
    assert table.startswith("Command: `dptpu eval cloud`") and "| 3 | 2 sigma | mf |" in table
    assert "dptpu wrong %" in table and "Goals of issue #16 met:" in table
    saved = json.loads(result.files["json"].read_text())
    # goals: 12-step at every noise (0, 2 sigma) and 3-step at 2 sigma, each for classical and dptpu
    assert len(saved["rows"]) == 8 and len(saved["goals"]) == 3 * 2
    assert saved["spec"]["rigs"][0]["focal_px"] == 1800.0


def test_the_outside_rigs_differ_from_the_training_rigs():
    # training: nominal (2600 px, 6.21 deg, 800 mm) and wide (1000 px, 8 deg, 700 mm)
    for rig in OUTSIDE_RIGS:
        assert rig.focal_px not in (2600.0, 1000.0) and rig.angle_deg not in (6.21, 8.0)
    assert OUTSIDE_RIGS[0].baseline_mm == pytest.approx(150.0, abs=0.1)
    built = OUTSIDE_RIGS[0].rig((96, 72))
    assert built.camera.size == (96, 72) and np.isclose(built.camera.K[0, 0], 1800.0 * 96 / 640)


def test_bad_specs_are_refused():
    with pytest.raises(ValueError, match="methods must be among mf, mw, nt"):
        CloudEvalSpec(methods=("graycode",))
    with pytest.raises(ValueError, match="CFPE scenes are 01, 04, 06, 08"):
        CloudEvalSpec(cfpe_scenes=("99",))


def test_real_cfpe_scores_the_published_orders_against_the_12_step_reference(cfpe_dir):
    from dptpu.experiments.cloud_eval import cfpe_rows
    from dptpu.sim.diagnosis.cfpe_inputs import cfpe_pair

    # classical only: the 3-step three-period heterodyne, every pixel kept (min_confidence 0)
    row, compensated = cfpe_rows(cfpe_dir, ["06"], min_confidence=0.0)
    pair = cfpe_pair(cfpe_dir, "06")
    at_reference = np.count_nonzero(pair.valid & (pair.coarse_order == pair.reference_order))
    assert (row["response"], row["solver"]) == ("as captured", "classical")
    assert row["truly_valid"] == np.count_nonzero(pair.valid)
    assert row["published"] - row["wrong"] == at_reference  # every published pixel at the reference order counts
    assert row["at_reference"] == pytest.approx(0.70112, abs=5e-5)  # measured 2026-11-26: real 3-step noise
    # the projector's response, calibrated on scenes 01, 04, 08 (0.16 rad at three times the phase), removed from
    # scene 06's 3-step phases: the beat levels of the heterodyne come right (measured 99.55 % at the reference)
    assert compensated["response"] == "compensated" and compensated["phase_error_rad"] == pytest.approx(0.16, abs=0.01)
    assert compensated["at_reference"] > 0.99 and compensated["completeness"] > 0.99
    # the default confidence threshold drops pixels near MF's rounding margin: fewer points, more of them right
    kept, _ = cfpe_rows(cfpe_dir, ["06"])
    assert kept["published"] < row["published"] and kept["at_reference"] > row["at_reference"] + 0.04, kept


def test_real_cfpe_meets_the_goal_with_the_network_once_the_projector_response_is_compensated(cfpe_dir):
    """Issue #16's goal on the real CFPE captures: >= 99.5 % of the published points at the reference order. As
    captured the 3-step phases put whole beat periods wrong (DP-TPU 94.7 %); compensated by the response fitted on
    the other scenes, DP-TPU on scene 04 has 99.97 % of 99.5 % of the pixels right (measured 2026-11-26)."""
    from dptpu.experiments.cloud_eval import cfpe_rows

    rows = cfpe_rows(cfpe_dir, ["04"], [FringeOrderModel.load(shipped_model_path())])
    by = {(r["response"], r["solver"]): r for r in rows}
    assert by[("as captured", "dptpu")]["at_reference"] < 0.97
    network = by[("compensated", "dptpu")]
    assert network["at_reference"] >= 0.995 and network["completeness"] > 0.98, network


def test_islands_of_a_wrong_order_on_a_blender_scene_are_dropped_and_nothing_right_with_them():
    """The shipped Blender scene random-1 (a renderer and rig the network never trained on; 64x12 + 1x12, MF): the
    network puts patches of the tori one order off where the interreflections between them bias the low frequency.
    The island filter takes them out, and no point of the right order goes with them (measured: 838 of the 1,085
    wrong-order points the other filters leave, none right)."""
    folder = Path(str(resources.files("dptpu.sim") / "shipped" / "01-random-1"))
    capture = read_capture(folder)
    rig = load_rig(capture.calibration)
    truth = np.load(folder / "gt.npz")
    truth_phase = 2 * np.pi * 64 * truth["projector_x"] / capture.fringe_extent_px
    result = refine_capture_result(unwrap_capture(capture, method="mf", high=64, low=1),
                                   FringeOrderModel.load(shipped_model_path()))

    def wrong_order(published):
        shift = np.where(truth["valid"], order_shift(result.absolute_phase, truth_phase), 0)
        return published & (np.nan_to_num(shift) != 0)

    kept, _, _ = published_cloud(result, rig, capture.fringe_extent_px, capture.fringe_axis, islands=False)
    published, _, dropped = published_cloud(result, rig, capture.fringe_extent_px, capture.fringe_axis)
    on_islands = kept & ~published
    assert dropped["islands"] == np.count_nonzero(on_islands) > 0
    assert np.count_nonzero(wrong_order(on_islands)) == np.count_nonzero(on_islands)  # every one wrong
    assert np.count_nonzero(wrong_order(on_islands)) >= 0.7 * np.count_nonzero(wrong_order(kept))
