"""Downstream gain (dptpu twin finetune): the pipeline's numbers, the ONNX weight loader, the measured pairs.

The pipeline test hides a strong projector gamma (2.2) in a synthetic "measured" pair and runs the whole
comparison at toy sizes (160x120, two scenes, two fine-tune epochs of two steps): it checks that the numbers are
consistent (same pixels, accuracies in [0, 1], every accuracy equal to one computed independently), not the
direction of the gain, which so few steps do not make robust (the real runs are in docs/sim-to-real.md). The
scoring's neighbour vote is checked on an analytic order map; the CFPE extension's projector gamma against the
closed form of a pure second harmonic. The cascade (CFPE's heterodyne as two MF pairs, a solver at each level):
on an analytic beat-level failure, on the real scene 06 with the shipped model, and its twin samples built by the
same code as the measured pairs.
"""
from dataclasses import replace

import numpy as np
import pytest

from dptpu.fpp import tpu
from dptpu.fpp.measured_data import shared_data_dir

DATA = shared_data_dir()
CFPE = DATA / "cfpe"
SPHERE = DATA / "dptpu-sphere"
GAMMA = 2.2


@pytest.fixture(scope="module")
def base_onnx(tmp_path_factory):
    """A seeded, untrained DP-TPU network exported to ONNX (the base model of the toy runs)."""
    import torch

    from dptpu.models.export import export_onnx
    from dptpu.models.factory import build_model

    torch.manual_seed(0)
    model = build_model("dptpu")
    with torch.no_grad():  # non-trivial weights everywhere, the output head included
        for parameter in model.parameters():
            parameter.add_(0.01 * torch.randn_like(parameter))
    path = export_onnx(model, tmp_path_factory.mktemp("base") / "base.onnx")
    return path, {k: v.clone() for k, v in model.state_dict().items()}


def test_onnx_weights_round_trip(base_onnx):
    from dptpu.models.onnx_weights import load_onnx_model

    path, state = base_onnx
    model, training = load_onnx_model(path)
    recovered = model.state_dict()
    assert set(recovered) == set(state)
    for key, value in state.items():  # every parameter, the constant-folded ones included
        np.testing.assert_allclose(recovered[key].numpy(), value.numpy(), rtol=1e-6, atol=1e-9, err_msg=key)
    assert training["max_abs_difference"] < 1e-4


def test_onnx_weights_of_an_untrained_network(tmp_path):
    """Untrained norms are all ones and zeros: the exporter merges them (Identity nodes); still recovered."""
    from dptpu.models.export import export_onnx
    from dptpu.models.factory import build_model
    from dptpu.models.onnx_weights import load_onnx_model

    model = build_model("dptpu")
    recovered, training = load_onnx_model(export_onnx(model, tmp_path / "fresh.onnx"))
    for key, value in model.state_dict().items():
        assert np.array_equal(recovered.state_dict()[key].numpy(), value.numpy()), key
    assert training["max_abs_difference"] == 0.0


def test_onnx_weights_refuses_a_foreign_file(tmp_path):
    from dptpu.models.onnx_weights import load_onnx_model

    path = tmp_path / "x.onnx"
    path.write_bytes(b"not a model")
    with pytest.raises(ValueError, match="x.onnx"):
        load_onnx_model(path)


def test_finetune_pipeline_numbers_are_consistent(base_onnx, tmp_path, capsys):
    from dptpu.experiments.downstream import DownstreamOptions, compare_finetunes, twin_set_pairs
    from dptpu.experiments.finetune import FinetuneOptions
    from dptpu.models.consensus import consensus_order
    from dptpu.models.inference import FringeOrderModel
    from dptpu.models.refine import refine_order
    from dptpu.sim.diagnosis.twin_pairs import PairDesign, write_twin_set
    from dptpu.sim.rig import nominal_rig

    rig = nominal_rig(camera_size=(160, 120))
    hidden = replace(rig, effects=({"projector_gamma": {"gamma": GAMMA}},))
    design = PairDesign("toy", (64.0, 1.0), (3, 3))
    measured_set = write_twin_set(hidden, design, tmp_path / "measured", scenes=1, size=(160, 120),
                                  noise=(3.1386,), seed=77)
    pairs = twin_set_pairs(measured_set)
    options = DownstreamOptions(scenes=2, size=(160, 120), noise=(3.1386,), heldout_scenes=0,
                                finetune=FinetuneOptions(epochs=2, batch=1, crop=(64, 64)))
    report = compare_finetunes(pairs, design, rig, hidden, tmp_path / "out", model=base_onnx[0], options=options,
                               progress=True)
    err = capsys.readouterr().err  # the bars of dptpu twin finetune: the twin sets, each fine-tune's epochs, scoring
    for bar in ("twin_baseline: 100%", "twin_extended: 100%", "epoch 2/2", "scoring: 100%"):
        assert bar in err, err
    assert "2/2 [" in err and "1/1 [" in err  # 2 scenes a set, 1 measured pair

    runs = report["finetune_runs"]
    assert runs["baseline"]["steps"] == runs["extended"]["steps"] == 4  # the same budget: 2 epochs x 2 samples
    (row,) = report["measured_results"]
    pair = pairs[0]
    assert row["pixels"] == int(pair.valid.sum()) > 1000
    assert set(row["accuracy"]) == {"classical", "base", "finetuned_baseline", "finetuned_extended"}
    assert all(0.0 <= a <= 1.0 for a in row["accuracy"].values())
    # the classical order: Eq. (5) recomputed here
    mf = tpu.unwrap_mf(pair.wrapped_high, pair.wrapped_low, 64.0, 1.0, valid=pair.valid).fringe_order
    expected = np.mean(mf[pair.valid] == pair.reference_order[pair.valid])
    assert row["accuracy"]["classical"] == pytest.approx(expected, abs=1e-12)
    # the strong gamma breaks the 3-step MF order on some pixels: there is something to correct
    assert row["accuracy"]["classical"] < 0.999
    # every solver scored twice, the same way: its own order, and after the same neighbour vote
    psi = np.where(pair.valid, pair.wrapped_high, 0.0)
    voted = consensus_order(pair.coarse_order, pair.coarse_order, psi, pair.valid)
    assert row["accuracy_vote"]["classical"] == pytest.approx(np.mean((voted == pair.reference_order)[pair.valid]),
                                                              abs=1e-12)
    for name, path in report["models"].items():  # each ONNX file run here as the unwrap node runs it
        order = refine_order(FringeOrderModel.load(path), "mf", pair.wrapped_high, pair.wrapped_low,
                             pair.coarse_order, 64.0, 1.0, pair.valid, consensus=False)
        voted = consensus_order(order, pair.coarse_order, psi, pair.valid)
        for key, result in (("accuracy", order), ("accuracy_vote", voted)):
            assert row[key][name] == pytest.approx(np.mean((result == pair.reference_order)[pair.valid]),
                                                   abs=1e-12), (name, key)
    # the two sets hold the same scenes: the same pixels are lit, only the frames differ
    lit = [np.load(p)["valid"].sum() for p in sorted((tmp_path / "out" / "twin_baseline" / "samples").glob("*.npz"))]
    assert len(lit) == 2 and min(lit) > 0
    assert (tmp_path / "out" / "finetuned_extended.onnx").is_file()


@pytest.mark.skipif(not (CFPE / "0600h.png").exists(), reason=f"CFPE data not found in {CFPE} (set DPTPU_DATA)")
def test_cfpe_three_step_inputs_against_the_twelve_step_phases():
    from dptpu.sim.diagnosis.cfpe_inputs import (
        FREQUENCIES,
        INPUT_STEPS,
        SHIFT_SIGN,
        _phases,
        cfpe_pair,
        input_rms,
        load_cfpe_frames,
    )

    # the 3-step phase of period 42 px is within 0.14 rad RMS of the 12-step one (measured 0.118 rad on scene 06:
    # 0.115 of it periodic in the phase, the projector's response; 0.025 random)
    rms = input_rms(CFPE, "06")
    assert 0.09 < rms["high_rad"] < 0.14
    assert rms["pixels"] > 250_000
    # het12: the MF order of the pair is the classical 3-step three-frequency heterodyne order (measured: the same
    # on 92 % of the pixels; 69 % of the others are pixels whose beat of beats fell below 0, which het12 reads as a
    # small negative phase and unwrap_heterodyne as one near 2 pi: het12 is right on 70.1 %, the heterodyne 68.8 %)
    pair = cfpe_pair(CFPE, "06")
    frames = load_cfpe_frames(CFPE, "06")
    psi3, mask3 = _phases(frames[:, list(INPUT_STEPS)])
    heterodyne = tpu.unwrap_heterodyne(psi3, FREQUENCIES, valid=mask3)
    both = pair.valid & heterodyne.valid
    assert np.mean(heterodyne.fringe_order[both] == pair.coarse_order[both]) > 0.9
    # measured: 70 % of the pixels have the 12-step order (the real projector response breaks the rest)
    accuracy = np.mean(pair.coarse_order[pair.valid] == pair.reference_order[pair.valid])
    assert 0.6 < accuracy < 0.8
    assert SHIFT_SIGN == 1


@pytest.mark.skipif(not (SPHERE / "standardball_phase_real.mat").exists(),
                    reason=f"DP-TPU sphere data not found in {SPHERE} (set DPTPU_DATA)")
def test_sphere_pair_reference_is_the_measured_sphere():
    from dptpu.fpp import real_sphere
    from dptpu.sim.diagnosis.sphere_inputs import sphere_errors_um, sphere_pair

    rig = real_sphere.load_rig(SPHERE, "real", relative_pose="all-views")
    pair = sphere_pair(SPHERE, noise_sigma=1.5693, rig=rig)
    assert pair.valid.sum() > 16_000  # of the 16,796 valid measured pixels
    errors = sphere_errors_um(pair, pair.reference_order, rig)
    # the reference orders give back the measured sphere: 27.6 um interior RMS, radius 25.400 mm (sim-to-real.md)
    assert errors["interior_sphere_rms_um"] == pytest.approx(27.6, abs=0.5)
    assert errors["interior_radius_mm"] == pytest.approx(25.400, abs=0.005)
    assert errors["point_error_rms_um"] == 0.0
    # the synthesized 1-sigma low phase breaks the classical MF order (96 x its noise) on some pixels
    accuracy = np.mean(pair.coarse_order[pair.valid] == pair.reference_order[pair.valid])
    assert 0.7 < accuracy < 0.95


def test_cli_refuses_a_folder_that_is_no_measured_data(tmp_path, capsys):
    from dptpu.cli.main import main

    code = main(["twin", "finetune", "--measured", str(tmp_path), "--extended", "x.yaml", "--model", "y.onnx",
                 "--out", str(tmp_path / "out")])
    assert code == 2
    assert f"{tmp_path}: neither a CFPE folder" in capsys.readouterr().err


def test_the_vote_scores_every_solver_alike_and_fixes_a_strip_of_jumped_orders():
    """An analytic order map: a tilted plane (1/7 period per pixel), the classical order right but for a strip
    3 px wide 15 orders off (a heterodyne's beat level failing) and two isolated pixels 1 order off; the vote,
    applied to the classical order itself, gives back every order."""
    from dptpu.experiments.downstream import evaluate_orders, solver_orders
    from dptpu.sim.diagnosis.measured_pair import MeasuredPair

    rows, columns = np.mgrid[0:48, 0:64]
    absolute = 2 * np.pi * (columns / 7.0 + rows / 23.0 + 0.3)  # radians of f_h
    reference = np.floor(absolute / (2 * np.pi)).astype(np.int32)
    classical = reference.copy()
    classical[:, 30:33] += 15
    classical[10, 10] += 1
    classical[40, 50] -= 1
    valid = np.ones(reference.shape, bool)
    psi = np.mod(absolute, 2 * np.pi)
    pair = MeasuredPair(name="toy", wrapped_high=psi, wrapped_low=np.mod(absolute / 20.0, 2 * np.pi),
                        coarse_order=classical, reference_order=reference, reference_phase=absolute, valid=valid,
                        frequency_high=20.0, frequency_low=1.0, method="mf", extent_px=64, provenance={})
    orders, voted = solver_orders({}, pair)
    row = evaluate_orders(pair, orders, voted=voted)
    assert row["accuracy"]["classical"] == pytest.approx(1 - (3 * 48 + 2) / (48 * 64))
    assert row["accuracy_vote"]["classical"] == 1.0


def test_cfpe_response_gamma_against_the_closed_form():
    """A square law ``p^2`` of ``o + a cos(theta)`` adds one harmonic, ``B_2 / B_1 = a / (4 o)``, which turns into
    exactly ``-B_2 / B_1 sin(3 psi)`` in a 3-step phase of shift sign +1 (the first term of ``arg(1 + r e^{3i psi})``):
    -0.1875 rad at CFPE's levels 128 + 96 cos. The gamma solved for that error is 2; a ray-cast twin scene
    rendered with it carries it within the 8-bit frames' rounding, and 0 without it."""
    from dptpu.fpp.phase_harmonics import HarmonicPhaseError
    from dptpu.sim.diagnosis.cfpe_response import matched_gamma, pattern_phase_error, rendered_phase_error
    from dptpu.sim.rig import nominal_rig

    square = [{"projector_gamma": {"gamma": 2.0}}]
    closed_form = -96 / (4 * 128)
    error = pattern_phase_error(square)
    assert error.sin_rad == pytest.approx(closed_form, abs=1e-9)
    assert abs(error.cos_rad) < 1e-9
    assert matched_gamma(HarmonicPhaseError(3, 0.0, closed_form)) == pytest.approx(2.0, abs=1e-6)
    rig = nominal_rig(camera_size=(96, 72))
    assert rendered_phase_error(rig, square).sin_rad == pytest.approx(closed_form, abs=0.005)
    assert abs(rendered_phase_error(rig, []).sin_rad) < 0.005
    with pytest.raises(ValueError, match="outside what a projector gamma"):
        matched_gamma(HarmonicPhaseError(3, 0.0, -0.9))


@pytest.mark.skipif(not (CFPE / "0600h.png").exists(), reason=f"CFPE data not found in {CFPE} (set DPTPU_DATA)")
def test_cfpe_extension_renders_the_real_response_and_the_vote_lifts_the_classical_order():
    from dptpu.experiments.downstream import DownstreamOptions, measured_pairs, solver_orders
    from dptpu.sim.diagnosis.cfpe_inputs import cfpe_phase_error
    from dptpu.sim.diagnosis.cfpe_response import cfpe_response_effects, pattern_phase_error
    from dptpu.sim.diagnosis.measured_pair import order_accuracy

    # the real 3-step phases carry -0.145 .. -0.167 rad x sin(3 psi) (per scene); the extension renders the same
    effects, measured = cfpe_response_effects(CFPE, ("01", "04", "06", "08"))
    assert -0.17 < measured.sin_rad < -0.145 and abs(measured.cos_rad) < 0.005
    assert 1.7 < effects[0]["projector_gamma"]["gamma"] < 2.0
    assert pattern_phase_error(effects).sin_rad == pytest.approx(measured.sin_rad, abs=1e-4)
    assert cfpe_phase_error(CFPE, ["08"]).sin_rad == pytest.approx(measured.sin_rad, abs=0.02)
    # scene 06 as captured and compensated (calibrated on 01, 04, 08): the classical order right on 70 % and
    # > 99 % (measured 0.7011, 0.9939); the same neighbour vote on the classical order alone lifts the captured
    # one to > 95 % (measured 0.9781: the beat level's failures are strips a few pixels wide)
    _, pairs, _ = measured_pairs(CFPE, DownstreamOptions(cfpe_scenes=("06",), cfpe_low="het12"))
    captured, compensated = pairs
    assert (captured.name, compensated.name) == ("cfpe06", "cfpe06/compensated")
    assert "fitted on scenes 01, 04, 08" in compensated.provenance["response"]
    assert 0.65 < order_accuracy(captured.coarse_order, captured) < 0.75
    assert order_accuracy(compensated.coarse_order, compensated) > 0.99
    _, voted = solver_orders({}, captured)
    assert order_accuracy(voted["classical"], captured) > 0.95


@pytest.mark.skipif(not (CFPE / "0600h.png").exists(), reason=f"CFPE data not found in {CFPE} (set DPTPU_DATA)")
def test_cfpe_cascade_the_shipped_model_reads_the_beat_level_the_heterodyne_breaks():
    """Scene 06 as the cascade's two pairs: with the classical rounding at both levels it is the het12 pair's
    heterodyne order (all pixels but one whose beat of beats is 0.6 pi off); the shipped model, untrained on such
    pairs, is right at the beat level on 98.7 % of the pixels where the heterodyne is on 83.2 %, and at the top on
    93.9 % against 70.1 % (measured)."""
    from dptpu.experiments.downstream import DownstreamOptions, cascade_orders, measured_pairs
    from dptpu.models.inference import shipped_model_path
    from dptpu.sim.diagnosis.cfpe_inputs import cfpe_pair
    from dptpu.sim.diagnosis.measured_pair import order_accuracy

    _, (cascade,), _ = measured_pairs(CFPE, DownstreamOptions(cfpe_scenes=("06",), cfpe_responses=("captured",)))
    het12 = cfpe_pair(CFPE, "06")
    assert np.array_equal(cascade.top.valid, het12.valid)
    assert np.count_nonzero(cascade.top.coarse_order != het12.coarse_order) <= 1
    assert cascade.beat.frequency_high == pytest.approx(8.0) and cascade.offset == 2
    beat, top = cascade_orders({"shipped": str(shipped_model_path())}, cascade)
    assert 0.8 < order_accuracy(beat["classical"], cascade.beat) < 0.86
    assert order_accuracy(beat["shipped"], cascade.beat) > 0.98
    assert order_accuracy(top["classical"], cascade.top) < 0.72
    assert order_accuracy(top["shipped"], cascade.top) > 0.93


def test_cli_refuses_a_max_correction_that_is_no_number(tmp_path, capsys):
    from dptpu.cli.main import main

    code = main(["twin", "finetune", "--measured", str(tmp_path), "--extended", "cfpe-response", "--model",
                 "y.onnx", "--max-correction", "four", "--out", str(tmp_path / "out")])
    assert code == 2
    assert "--max-correction must be a whole number of orders >= 0 or 'none'; got 'four'" in capsys.readouterr().err


def _plane_phases(bad, periods=(42, 45, 48), width=1920, start=600.0, step=4.8):
    """Wrapped phases of three projector periods on a tilted plane (``step`` projector px a camera column from
    ``start``; chosen so that a beat period further is still on the projector), the lowest frequency's phase moved
    by ``2 pi f_123 / f_12`` on the pixels of ``bad`` (one level-1 order), and the frequencies and true phases."""
    rows, columns = np.mgrid[0:96, 0:128]
    x_p = start + step * columns + 0.4 * rows
    frequencies = [width / p for p in periods]
    f_12 = frequencies[0] - frequencies[1]
    f_123 = f_12 - (frequencies[1] - frequencies[2])
    assert x_p.max() + width / f_12 < width
    phi = [2 * np.pi * f * x_p / width for f in frequencies]
    psi = [np.mod(p, 2 * np.pi) for p in phi]
    psi[2] = np.mod(psi[2] + np.where(bad, 2 * np.pi * f_123 / f_12, 0.0), 2 * np.pi)
    return psi, phi, frequencies


@pytest.mark.parametrize("periods, width, start, step", [
    ((42, 45, 48), 1920, 600.0, 4.8),  # CFPE: level-1 ratio 8, the top 15 orders a beat order
    ((20, 21, 22), 1000, 150.0, 2.5),  # ratio 11, 21 orders
    ((30, 32, 34), 1280, 200.0, 4.0),  # ratio 8.5, 16 orders
])
def test_cascade_corrects_a_beat_level_jump_the_heterodyne_makes(periods, width, start, step):
    """A synthetic beat-level failure: the lowest frequency's phase moved on 5 % of the pixels (random) and on a
    strip 2 px wide by one level-1 order's worth (``2 pi f_123 / f_12``: the beat of beats moves by it, ``f_12 /
    f_123`` times that is one order): the heterodyne (= the classical cascade) is exactly ``f_0 / f_12`` orders
    off there and right elsewhere; the beat pair sees a one-order error of its prior, which the shipped network
    mostly takes out. Measured: CFPE's periods every order back; 20/21/22 of 1000 px 98.9 % of the jumped pixels,
    30/32/34 of 1280 px 87.3 % (the strip is what is left), 0.00-0.22 % of the others broken."""
    from dptpu.experiments.downstream import _score, _vote, cascade_orders
    from dptpu.models.inference import shipped_model_path
    from dptpu.sim.diagnosis.beat_cascade import cascade_pair

    rows, columns = np.mgrid[0:96, 0:128]
    bad = (np.random.default_rng(0).random(rows.shape) < 0.05) | ((columns >= 60) & (columns < 62))
    psi, phi, frequencies = _plane_phases(bad, periods, width, start, step)
    cascade = cascade_pair("plane", psi, np.ones(bad.shape, bool), phi[0], frequencies, extent_px=width)
    heterodyne = tpu.unwrap_heterodyne(psi, frequencies)
    assert np.array_equal(cascade.top.coarse_order, heterodyne.fringe_order)
    jump = round(frequencies[0] / (frequencies[0] - frequencies[1]))
    error = cascade.top.coarse_order - cascade.top.reference_order
    assert np.all(error[bad] == jump) and np.all(error[~bad] == 0)
    assert np.all((cascade.beat.coarse_order - cascade.beat.reference_order)[bad] == 1)
    models = {"shipped": str(shipped_model_path())}
    beat, top = cascade_orders(models, cascade)
    right = top["shipped"] == cascade.top.reference_order
    assert right[bad].mean() > 0.85 and right[~bad].mean() > 0.995
    if periods == (42, 45, 48):
        assert np.array_equal(beat["shipped"], cascade.beat.reference_order) and right.all()
    # the report's row: the top level's accuracy, after the vote, and the beat level's
    row = _score(models, cascade, 1)
    assert row["accuracy"] == {"classical": pytest.approx(1 - bad.mean(), abs=1e-12),
                               "shipped": pytest.approx(right.mean(), abs=1e-12)}
    assert row["accuracy_beat"]["shipped"] == pytest.approx(np.mean(beat["shipped"] == cascade.beat.reference_order))
    # the vote at each level: level 1's orders voted, level 2 built from them, the top voted
    _, levels = cascade_orders(models, cascade, vote_beat=True)
    voted = _vote(levels, cascade.top)
    for name in ("classical", "shipped"):
        expected = np.mean(voted[name] == cascade.top.reference_order)
        assert row["accuracy_vote_levels"][name] == pytest.approx(expected, abs=1e-12), name
    if periods == (42, 45, 48):
        assert row["accuracy_vote"]["shipped"] == row["accuracy_vote_levels"]["shipped"] == 1.0


def test_twin_cascade_samples_are_built_like_the_measured_cascade(tmp_path):
    """The twin's two samples per render: level 1 (f_h = 8, its classical order) and level 2 (f_h = 45.71, the low
    phase of the right beat order); the classical cascade of the same render is the het12 pair's order (the
    heterodyne's, but for a beat of beats fallen below 0 at the projector's first columns, which het12 and the
    cascade read as negative, :func:`dptpu.fpp.tpu.unwrap_heterodyne` as near 2 pi)."""
    from dptpu.sim.diagnosis.beat_cascade import cascade_pair
    from dptpu.sim.diagnosis.cfpe_inputs import build_pair
    from dptpu.sim.diagnosis.cfpe_response import cfpe_twin_rig
    from dptpu.sim.diagnosis.twin_pairs import CFPE_CASCADE_DESIGN, _render_inputs, write_twin_set
    from dptpu.sim.rig import nominal_rig
    from dptpu.sim.scenes import random_scene

    rig = cfpe_twin_rig(nominal_rig(camera_size=(128, 96)))
    folder = write_twin_set(rig, CFPE_CASCADE_DESIGN, tmp_path / "set", scenes=1, size=(128, 96), noise=(3.1386,))
    level1, level2 = (np.load(p) for p in sorted((folder / "samples").glob("*.npz")))
    assert float(level1["frequency_high"]) == pytest.approx(8.0)
    assert float(level2["frequency_high"]) == pytest.approx(1920 / 42)
    assert level1["valid"].sum() > 1000 and level2["valid"].sum() > 1000
    # labels only within 4 orders of each level's classical order
    for sample in (level1, level2):
        valid = sample["valid"]
        assert np.all(np.abs(sample["coarse_order"][valid] - sample["label_order"][valid]) <= 4)
    inputs = _render_inputs(rig, random_scene(rig, yaml_seed(folder)), CFPE_CASCADE_DESIGN, noise_sigma=3.1386,
                            seed=yaml_seed(folder))
    cascade = cascade_pair("twin", inputs["psi"], inputs["usable"], inputs["reference"],
                           CFPE_CASCADE_DESIGN.frequencies, extent_px=1920)
    assert np.array_equal(cascade.beat.wrapped_high.astype(np.float32)[level1["valid"]],
                          level1["wrapped_high"][level1["valid"]])
    het12 = build_pair("twin", inputs["psi"], inputs["usable"], inputs["reference"],
                       CFPE_CASCADE_DESIGN.frequencies, extent_px=1920, low="het12")
    assert np.array_equal(het12.valid, cascade.top.valid) and het12.valid.sum() > 1000
    assert np.count_nonzero(het12.coarse_order != cascade.top.coarse_order) <= 2


def yaml_seed(folder) -> int:
    """The scene seed of a one-scene twin set's first sample."""
    return int(np.load(sorted((folder / "samples").glob("*.npz"))[0])["scene_seed"])
