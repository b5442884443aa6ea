"""unwrap_capture on synthetic PNG captures: every method recovers the true fringe orders.

The synthetic scene (tests/conftest.py) is a camera that sees integer projector columns ``x_p`` with a
raised box and an isolated island (depth discontinuities) and a shadow; its frames are
``fringe_patterns`` sampled at ``x_p``, scaled by an albedo, plus Gaussian noise, in 8 bits. The true
order is ``floor(f x_p / W)``; pixels within 2 % of a period of a fringe boundary (where the true
phase is a multiple of 2 pi and noise may put ``psi`` on either side) are left out of the order check,
but their absolute phase is checked like every other pixel.
"""
import cv2
import numpy as np
import pytest

from dptpu.cli.main import main
from dptpu.fpp.capture import read_capture
from dptpu.fpp.reconstruct import DEFAULT_MIN_MODULATION_FRACTION, unwrap_capture

EXTENT = 912  # synthetic projector width (fringe axis x)
BOUNDARY_MARGIN = 0.02  # periods
PHASE_TOLERANCE_RAD = 0.05  # measured max error 0.011-0.015 rad (8-bit frames, 0.5 DN noise)

METHOD_SPECS = {
    "mf": [{"frequency": 64}, {"frequency": 1}],
    "mw": [{"frequency": 64}, {"frequency": 63}],
    "nt": [{"period": 30}, {"period": 31}],  # LCM(30, 31) = 930 >= 912
    "heterodyne": [{"period": 42}, {"period": 45}, {"period": 48}],  # CFPE's periods
    "graycode": [{"period": 16},
                 {"kind": "graycode", "bits": 6, "period": 16, "inverse": True, "complementary": True}],
}


def assert_matches_truth(fringe_order, absolute_phase, valid, frequency, scene, *, min_lit_valid=0.99):
    """Orders exact away from fringe boundaries, absolute phase within tolerance, shadow invalid."""
    cycles = frequency * scene.projector_x / EXTENT  # (H, W), true phi / 2 pi
    true_order = np.floor(cycles)
    fraction = cycles - true_order
    interior = valid & (fraction > BOUNDARY_MARGIN) & (fraction < 1 - BOUNDARY_MARGIN)
    assert interior.sum() > 0.9 * valid.sum()
    np.testing.assert_array_equal(fringe_order[interior], true_order[interior])
    phase_error = np.abs(absolute_phase[valid] - 2 * np.pi * cycles[valid])
    assert phase_error.max() < PHASE_TOLERANCE_RAD
    assert valid[scene.lit].mean() >= min_lit_valid
    assert not valid[~scene.lit].any()


@pytest.mark.parametrize("method", sorted(METHOD_SPECS))
def test_cli_unwrap_recovers_true_fringe_orders(synthetic_capture, tmp_path, capsys, method):
    folder, scene = synthetic_capture(METHOD_SPECS[method], name=method)
    out = tmp_path / f"{method}.npz"

    assert main(["unwrap", "--capture", str(folder), "--method", method, "--out", str(out)]) == 0

    with np.load(out) as result:
        assert result["valid"].dtype == bool
        frequency = float(result["frequency"])
        assert_matches_truth(result["fringe_order"], result["absolute_phase"], result["valid"], frequency, scene)
        assert f"{int(result['valid'].sum())} of {scene.lit.size} pixels valid" in capsys.readouterr().out
    expected_high = {"mf": 64, "mw": 64, "nt": EXTENT / 30, "heterodyne": EXTENT / 42, "graycode": EXTENT / 16}
    assert frequency == pytest.approx(expected_high[method], rel=1e-12)


def test_modulation_and_reliability_are_reported(synthetic_capture):
    folder, scene = synthetic_capture(METHOD_SPECS["mf"])
    result = unwrap_capture(read_capture(folder), method="mf")
    # Camera level = 8 + 0.9 * albedo * 255 * (0.5 + 0.45 cos(.)) -> B = 0.9 * 0.45 * 255 * albedo.
    expected = 0.9 * 0.45 * 255 * scene.albedo
    np.testing.assert_allclose(result.modulation[scene.lit], expected[scene.lit], atol=1.0)
    assert result.reliability[~result.valid].max() == 0.0
    assert np.median(result.reliability[result.valid]) > 0.9  # MF with f_h/f_l = 64 and tiny noise
    assert result.method == "mf" and result.frequencies == (64.0, 1.0)
    assert result.fringe_axis == "x" and result.projector_size == (912, 1140)


def test_phase_shift_sign_and_phase_offset_are_honoured(synthetic_capture):
    specs = [{"period": 42, "phase_offset": 0.7}, {"period": 45, "phase_offset": -1.3}, {"period": 48}]
    folder, scene = synthetic_capture(specs, phase_shift_sign=1)
    capture = read_capture(folder)
    assert capture.phase_shift_sign == 1 and capture.sequences[0].phase_offset == 0.7

    result = unwrap_capture(capture, method="heterodyne")

    assert_matches_truth(result.fringe_order, result.absolute_phase, result.valid, EXTENT / 42, scene)


def test_declaring_the_wrong_phase_shift_sign_breaks_the_orders(synthetic_capture):
    folder, scene = synthetic_capture(METHOD_SPECS["heterodyne"], phase_shift_sign=1)
    text = (folder / "capture.yaml").read_text()
    (folder / "capture.yaml").write_text(text.replace("phase_shift_sign: 1", "phase_shift_sign: -1"))

    result = unwrap_capture(read_capture(folder), method="heterodyne")

    # The mirrored phases put x_p at 5040 - x_p (the heterodyne range), off the projector: all invalid.
    assert result.valid.mean() < 0.01


def test_default_and_chosen_sequences(synthetic_capture):
    folder, scene = synthetic_capture([{"frequency": 63}, {"frequency": 1}, {"frequency": 64}])
    capture = read_capture(folder)

    assert unwrap_capture(capture, method="mf").frequencies == (64.0, 1.0)
    assert unwrap_capture(capture, method="mw").frequencies == (64.0, 63.0)
    chosen = unwrap_capture(capture, method="mf", high=63, low=1)
    assert chosen.frequencies == (63.0, 1.0)
    assert_matches_truth(chosen.fringe_order, chosen.absolute_phase, chosen.valid, 63.0, scene)
    with pytest.raises(ValueError, match=r"nt takes the one other frequency by default.*choose the low one with --low"):
        unwrap_capture(capture, method="nt")


def test_frequency_given_by_period_is_found_within_a_relative_1e3(synthetic_capture):
    folder, _ = synthetic_capture(METHOD_SPECS["heterodyne"][:2] + [{"frequency": 1}])
    capture = read_capture(folder)
    result = unwrap_capture(capture, method="mf", high=20.27)  # 912 / 45 = 20.2667
    assert result.frequency == pytest.approx(912 / 45, rel=1e-12)


@pytest.mark.parametrize("specs, method, options, message", [
    (METHOD_SPECS["mf"], "mf", {"high": 50}, r"unknown frequency 50 \(--high\); the capture has "
                                            r"phase sequences of frequency 64, 1"),
    (METHOD_SPECS["mf"], "mw", {}, r"mw needs a low frequency with 0 < f_h - f_l <= 1 for f_h = 64"),
    (METHOD_SPECS["mf"], "heterodyne", {"high": 64}, r"heterodyne unwraps with every frequency and gives the highest"),
    (METHOD_SPECS["mf"], "graycode", {}, r"graycode needs a sequence of kind 'graycode'"),
    (METHOD_SPECS["mf"], "mf", {"high": 64, "low": 64}, r"--low 64 is the high frequency 64"),
    (METHOD_SPECS["mf"][:1], "mf", {}, r"mf needs two or more frequencies; the capture has phase sequences of "
                                       r"frequency 64$"),
    (METHOD_SPECS["mw"], "mf", {}, r"mf needs a low frequency <= 1 .*the capture has phase sequences of "
                                   r"frequency 64, 63: use heterodyne or nt"),
    (METHOD_SPECS["mf"], "spatial", {}, r"unknown unwrapping method 'spatial'"),
    ([{"frequency": 64}, {"frequency": 64}, {"frequency": 1}], "mf", {},
     r"frequency 64 appears 2 times; mf needs the frequencies it uses to be distinct"),
    ([{"frequency": 64}, {"frequency": 63}, {"frequency": 63}], "heterodyne", {},
     r"frequency 63 appears 2 times; heterodyne needs the frequencies it uses to be distinct"),
    ([{"period": 20}, {"kind": "graycode", "bits": 6, "period": 16}], "graycode", {},
     r"no phase sequence has the period of the Gray code \(period 16"),
])
def test_unusable_choices_raise_value_error(synthetic_capture, specs, method, options, message):
    folder, _ = synthetic_capture(specs)
    with pytest.raises(ValueError, match=message):
        unwrap_capture(read_capture(folder), method=method, **options)


@pytest.mark.parametrize("code, references", [
    ({"inverse": False, "complementary": True}, True),   # white/black thresholds
    ({"inverse": False, "complementary": True}, False),  # threshold at the phase background
    ({"inverse": True, "complementary": False}, False),  # plain Gray code
])
def test_graycode_binarization_variants(synthetic_capture, code, references):
    folder, scene = synthetic_capture([{"period": 16}, {"kind": "graycode", "bits": 6, "period": 16, **code}],
                                      with_references=references)
    assert bool(read_capture(folder).references) == references

    result = unwrap_capture(read_capture(folder), method="graycode")

    if code["complementary"]:
        assert_matches_truth(result.fringe_order, result.absolute_phase, result.valid, EXTENT / 16, scene)
    else:  # a plain code is wrong by one order exactly at code boundaries; check away from them
        cycles = EXTENT / 16 * scene.projector_x / EXTENT
        fraction = cycles % 1
        away = result.valid & (fraction > 0.1) & (fraction < 0.9)
        np.testing.assert_array_equal(result.fringe_order[away], np.floor(cycles)[away])
        assert result.valid[scene.lit].mean() > 0.99


def test_saturated_pixels_are_invalid(synthetic_capture):
    folder, scene = synthetic_capture(METHOD_SPECS["mf"])
    capture = read_capture(folder)
    frame = capture.sequences[1].images[5]  # one frame of the low-frequency sequence
    image = cv2.imread(str(frame), cv2.IMREAD_UNCHANGED)
    image[40:44, 30:40] = 255  # a specular highlight
    cv2.imwrite(str(frame), image)

    result = unwrap_capture(capture, method="mf")

    assert not result.valid[40:44, 30:40].any()
    assert result.valid[scene.lit].sum() == scene.lit.sum() - 40
    below = unwrap_capture(capture, method="mf", saturation_level=256, max_noise_ratio=0)  # no level reaches 256
    assert below.valid[40:44, 30:40].all()
    # the frame that left the sinusoid is the fit's residual: the phase-noise test (fpp.fringe_noise) drops it too
    assert not unwrap_capture(capture, method="mf", saturation_level=256).valid[40:44, 30:40].any()


def test_min_modulation_threshold(synthetic_capture):
    folder, scene = synthetic_capture(METHOD_SPECS["mf"])
    capture = read_capture(folder)
    assert DEFAULT_MIN_MODULATION_FRACTION * 255 == pytest.approx(5.1)

    result = unwrap_capture(capture, method="mf", min_modulation=80.0)

    expected_modulation = 0.9 * 0.45 * 255 * scene.albedo  # 62 .. 103 DN on lit pixels
    assert not result.valid[expected_modulation < 78].any()
    assert result.valid[expected_modulation > 82].all()
    assert 0.3 < result.valid.mean() < 0.7
