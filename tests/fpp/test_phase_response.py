"""The projector's phase response as a rig calibration: `dptpu calibrate response` on a twin capture of a gamma
projector, the rig file's `projector.phase_response`, and `dptpu unwrap` / `unwrap_capture` applying it."""
import dataclasses
import shutil

import numpy as np
import pytest
import yaml

from dptpu.cli.main import main
from dptpu.fpp.calibration import load_rig, save_opencv_rig, save_rig
from dptpu.fpp.capture import read_capture
from dptpu.fpp.phase_harmonics import HarmonicPhaseError, ProjectorPhaseResponse, remove_harmonic_phase_error
from dptpu.fpp.phase_response_calibration import calibrate_phase_response
from dptpu.fpp.reconstruct import unwrap_capture
from dptpu.sim.image_formation import parse_sequences
from dptpu.sim.render import render_capture
from dptpu.sim.rig import nominal_rig
from dptpu.sim.scenes import load_scene

GAMMA = 2.2
NOISE = ({"sensor_noise": {"read_noise_dn": 1.0}},)
FREQUENCY, EXTENT_PX = 16.0, 912  # 16 periods over the nominal projector's 912 columns


def _rig(*effects):
    return dataclasses.replace(nominal_rig(camera_size=(160, 120)), effects=tuple(effects))


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    """A gamma projector's 12-step and 3-step plane (the calibration), its 3-step MF sphere (the scan), and the same
    sphere through a linear projector (the noise floor); 1 DN read noise on all."""
    root = tmp_path_factory.mktemp("response")
    gamma = {"projector_gamma": {"gamma": GAMMA}}
    render_capture(_rig(gamma, *NOISE), load_scene("plane", _rig()), parse_sequences("16x12,16x3"), root / "cal",
                   seed=1)
    render_capture(_rig(gamma, *NOISE), load_scene("sphere", _rig()), parse_sequences("16x3,1x3"), root / "scan",
                   seed=2)
    render_capture(_rig(*NOISE), load_scene("sphere", _rig()), parse_sequences("16x3,1x3"), root / "linear", seed=2)
    assert main(["calibrate", "response", str(root / "cal"), "--out", str(root / "response.yaml")]) == 0
    return root


def _phase_error(result, capture):
    """RMS of the absolute phase against the twin's truth (radians), and the share of right orders."""
    gt = np.load(capture.ground_truth)
    both = result.valid & gt["valid"]
    truth = 2 * np.pi * FREQUENCY * gt["projector_x"] / EXTENT_PX
    error = (result.absolute_phase - truth)[both]
    wrapped = np.angle(np.exp(1j * error))
    return float(np.sqrt(np.mean(wrapped ** 2))), float(np.mean(np.rint(error / (2 * np.pi)) == 0))


def test_the_fitted_3_step_error_is_the_gamma_patterns_harmonics(twin):
    """First order, the 3-step phase error of harmonics B_k is (B_4 - B_2) / B_1 sin(3 psi) (k = 2 and 4 alias onto
    the fundamental); the pattern 0.5 + 0.45 cos raised to 2.2 gives 0.2589 rad."""
    theta = np.linspace(0.0, 2 * np.pi, 4096, endpoint=False)
    harmonics = np.abs(np.fft.rfft((0.5 + 0.45 * np.cos(theta)) ** GAMMA))
    first_order = (harmonics[2] - harmonics[4]) / harmonics[1]
    error = load_rig(twin / "response.yaml").phase_response.for_steps(3)
    assert error.sin_rad == pytest.approx(-first_order, rel=0.02)  # measured -0.2609
    assert abs(error.cos_rad) < 0.01 * first_order  # a gamma's harmonics are in phase with the fundamental


def test_a_capture_calibrates_from_its_own_3_step_sequence_and_from_the_12_step_frames(twin):
    """Steps 0, 4, 8 of the 12 and the separate 3-step sequence of the same frequency are two pairs of one fit; 4 and
    6 steps come from the 12 alone; the first term fitted alone is the three-term fit's first term."""
    capture = read_capture(twin / "cal")
    fits = calibrate_phase_response([capture]).fits
    assert sorted(fits) == [3, 4, 6] and len(fits[4].pairs) == len(fits[6].pairs) == 1
    assert [label.split(", ")[-1] for label in fits[3].pairs] == ["3 of the 12 steps", "the 3-step sequence"]
    assert fits[3].rms_after_rad < 0.15 * fits[3].rms_before_rad  # measured 0.187 -> 0.0174 rad over both pairs
    alone = calibrate_phase_response([capture], steps=[3], multiples=1).fits[3].error
    assert alone.sin_rad == pytest.approx(fits[3].error.sin_rad, abs=0.002)


def test_the_calibrated_response_takes_the_3_step_error_of_another_scene_to_the_noise(twin):
    """Calibrated on the plane, applied to the sphere: the 3-step phase error falls to that of a linear projector
    with the same noise (measured 0.190 -> 0.0351 rad RMS, floor 0.0351), and MF's orders from 71 % to 100 % right."""
    scan = read_capture(twin / "scan")
    response = load_rig(twin / "response.yaml").phase_response
    before, right_before = _phase_error(unwrap_capture(scan, method="mf"), scan)
    after, right_after = _phase_error(unwrap_capture(scan, method="mf", phase_response=response), scan)
    linear = read_capture(twin / "linear")
    floor, _ = _phase_error(unwrap_capture(linear, method="mf"), linear)
    assert before > 4 * floor and right_before < 0.8
    assert after < 1.1 * floor and right_after > 0.999


def test_dptpu_unwrap_applies_the_rigs_response_and_without_it_gives_todays_output(twin, tmp_path, capsys):
    scan = read_capture(twin / "scan")
    plain, corrected = tmp_path / "plain.npz", tmp_path / "corrected.npz"
    assert main(["unwrap", "--capture", str(twin / "scan"), "--method", "mf", "--model", "none",
                 "--min-confidence", "0", "--out", str(plain)]) == 0
    assert "projector response" not in capsys.readouterr().out
    expected = unwrap_capture(scan, method="mf")
    with np.load(plain) as saved:  # the rig holds no response: bit for bit what unwrap_capture gives without one
        np.testing.assert_array_equal(saved["absolute_phase"], expected.absolute_phase)
        np.testing.assert_array_equal(saved["valid"], expected.valid)
    calibrated = tmp_path / "calibrated"
    shutil.copytree(twin / "scan", calibrated)
    shutil.copy(twin / "response.yaml", calibrated / "calibration.yaml")
    assert main(["unwrap", "--capture", str(calibrated), "--method", "mf", "--model", "none",
                 "--min-confidence", "0", "--out", str(corrected)]) == 0
    assert "projector response of the rig applied to 3-step phases" in capsys.readouterr().out
    response = load_rig(twin / "response.yaml").phase_response
    with np.load(corrected) as saved:
        np.testing.assert_array_equal(saved["absolute_phase"],
                                      unwrap_capture(scan, method="mf", phase_response=response).absolute_phase)


def test_other_step_counts_are_left_as_computed(twin):
    """A response of 4 steps only leaves a 3-step capture bit for bit as it was."""
    scan = read_capture(twin / "scan")
    four = ProjectorPhaseResponse({4: HarmonicPhaseError(4, 0.01, -0.02)})
    plain, untouched = unwrap_capture(scan, method="mf"), unwrap_capture(scan, method="mf", phase_response=four)
    for name in ("absolute_phase", "fringe_order", "valid", "reliability"):
        np.testing.assert_array_equal(getattr(untouched, name), getattr(plain, name))


def test_the_table_lookup_agrees_with_newtons_inversion():
    error = HarmonicPhaseError(3, 0.004, -0.26, (0.001, 0.0), (0.034, -0.006))
    psi = np.linspace(0.0, 2 * np.pi, 120 * 160, endpoint=False).reshape(120, 160)
    newton = remove_harmonic_phase_error(psi, error)
    response = ProjectorPhaseResponse({3: error})
    for phase, offset in ((psi, 0.0), (psi.astype(np.float32), 0.0), (np.mod(psi - 0.7, 2 * np.pi), 0.7)):
        corrected = response.correct(phase, 3, phase_offset=offset)
        assert corrected.dtype == phase.dtype and 0 <= corrected.min() and corrected.max() < 2 * np.pi
        # the error is a function of the pattern's phase psi + offset
        difference = np.angle(np.exp(1j * (corrected + offset - newton)))
        assert np.abs(difference).max() < (1e-5 if phase.dtype == np.float64 else 2e-5)
    assert response.correct(psi, 4) is psi


def _rig_with_response():
    error = HarmonicPhaseError(3, 0.0008, -0.1575, (0.0001, 0.0), (0.0144, -0.0011))
    return dataclasses.replace(_rig(), phase_response=ProjectorPhaseResponse({
        3: error, 4: HarmonicPhaseError(4, 0.0003, 0.0148)}))


@pytest.mark.parametrize("writer", [save_rig, save_opencv_rig])
def test_the_rig_file_round_trip_keeps_the_response(tmp_path, writer):
    rig = _rig_with_response()
    read = load_rig(writer(rig, tmp_path / "rig.yaml")).phase_response
    assert read.steps == (3, 4)
    for steps in (3, 4):
        np.testing.assert_allclose(read.errors[steps].terms, rig.phase_response.errors[steps].terms, atol=1e-15)
    assert load_rig(save_rig(_rig(), tmp_path / "plain.yaml")).phase_response is None
    assert "phase_response" not in (tmp_path / "plain.yaml").read_text()


@pytest.mark.parametrize("field, message", [
    ("[0.1, 0.2]", "projector.phase_response must be a mapping of step counts"),
    ("{2: {cos_rad: 0.0, sin_rad: 0.1}}", "keys are step counts, integers in [3, 1000]; got 2"),
    ("{3: {cos_rad: 0.0}}", "projector.phase_response[3] must be {cos_rad: R, sin_rad: R}"),
    ("{3: {cos_rad: 0.0, sin_rad: .nan}}", "projector.phase_response[3].sin_rad must be a finite number"),
    ("{3: {cos_rad: [0.0, 0.1], sin_rad: [0.1]}}", "cos_rad and sin_rad must list as many terms; got 2 and 1"),
    ("{3: {cos_rad: 0.0, sin_rad: 0.4}}", "the error's slope must stay above -1 (for one term: amplitude below"),
])
def test_a_malformed_phase_response_is_refused_in_one_line_with_exit_2(twin, tmp_path, capsys, field, message):
    capture = tmp_path / "capture"
    shutil.copytree(twin / "scan", capture)
    document = yaml.safe_load((twin / "response.yaml").read_text())
    document["projector"]["phase_response"] = yaml.safe_load(field)
    (capture / "calibration.yaml").write_text(yaml.safe_dump(document))
    code = main(["unwrap", "--capture", str(capture), "--method", "mf", "--model", "none",
                 "--out", str(tmp_path / "out.npz")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert f"{capture / 'calibration.yaml'}: projector.phase_response" in err


def test_calibrate_response_needs_a_12_step_reference(twin, capsys):
    code = main(["calibrate", "response", str(twin / "scan"), "--out", str(twin / "never.yaml")])
    err = capsys.readouterr().err
    assert code == 2 and "no phase sequence of 12 or more steps to calibrate against" in err
    assert "16 x 3, 1 x 3" in err and not (twin / "never.yaml").exists()


@pytest.mark.parametrize("args, message", [
    (["--steps", "three"], "--steps must be step counts such as 3 or 3,4; got 'three'"),
    (["--steps", "2"], "--steps must be step counts >= 3; got '2'"),
    (["--steps", "5"], "no capture provides 5-step phases beside a reference of 12+ steps (available: 3, 4, 6)"),
    (["--board", "10x8:13"], "--twin and --board belong to the rig calibration; 'response' takes capture folders"),
])
def test_calibrate_response_refuses_bad_options_in_one_line(twin, tmp_path, capsys, args, message):
    code = main(["calibrate", "response", str(twin / "cal"), "--out", str(tmp_path / "rig.yaml"), *args])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "rig.yaml").exists()


def test_a_rig_calibration_still_needs_its_board(tmp_path, capsys):
    assert main(["calibrate", str(tmp_path), "--out", str(tmp_path / "rig.yaml")]) == 2
    assert "--board COLSxROWS:SQUARE_MM is required" in capsys.readouterr().err
