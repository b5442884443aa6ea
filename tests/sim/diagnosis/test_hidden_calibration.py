"""A calibration error hidden in captures from a rig the project was not built on (tests/outside_rigs.py): the
diagnosis names ``calibration_error`` with the hidden component within 20 %, writes the fitted rig as
``corrected_rig.yaml``, and answers "none" on a clean capture of the same rig.

One view of a sphere tells a turn of the projector, its sideways shift and the camera's principal point apart; it
does not tell the projector's focal scale from its distance (both scale the fringes on a small object), so those
two are not hidden here (docs/sim-to-real.md).
"""
import numpy as np
import pytest

from dptpu.fpp.calibration import load_rig
from dptpu.sim.diagnosis import diagnose
from dptpu.sim.diagnosis.calibration_fit import component_value, fit_calibration_error
from dptpu.sim.diagnosis.measured import load_measured
from dptpu.sim.diagnosis.pixels import erode_mask
from dptpu.sim.diagnosis.reference import parse_reference
from dptpu.sim.diagnosis.registration import register_robust
from dptpu.sim.diagnosis.report import write_report
from dptpu.sim.effects.calibration import miscalibrated_rig
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.outside_rigs import outside_rig
from dptpu.sim.render import render_capture
from dptpu.sim.scenes import load_scene

SEQUENCES = [SequenceSpec(96, 12), SequenceSpec(1, 12)]
SPHERE = "sphere:50.8082"
TOLERANCE = 0.2
TEST_PIXELS = 1000


@pytest.fixture(scope="module")
def rig():
    """An outside rig: camera f = 1800 px, the projector 150 mm to the side, turned in by 12 deg, 160x120."""
    return outside_rig(camera_focal_px=1800.0, baseline_mm=150.0, angle_deg=12.0, size=(160, 120))


def _capture(folder, rig, effects, seed):
    render_capture(rig, load_scene("sphere", rig), SEQUENCES, folder, effects=effects, seed=seed)
    return folder


@pytest.mark.parametrize("component, params", [
    ("translation_x", {"translation": [2.7, 0.0, 0.0]}),  # 1.8 % of the baseline, along the projector's x
    ("rotation_y_deg", {"rotation_deg": [0.0, -0.25, 0.0]}),
])
def test_hidden_calibration_error_is_named_and_sized(tmp_path, rig, component, params):
    folder = _capture(tmp_path / "measured", rig, [{"calibration_error": params}], seed=3)
    result = diagnose(folder, rig, reference=SPHERE, max_pixels=TEST_PIXELS)
    assert result.cause == "calibration_error", [(e["name"], round(e["gain"], 3)) for e in result.effects[:3]]
    entry = result.effects[0]
    assert entry["evidence"]["components"][0] == component
    true = component_value(params, component)
    assert abs(component_value(entry["parameters"], component) - true) <= TOLERANCE * abs(true)
    assert entry["gain"] > 0.3
    report = write_report(result, tmp_path / "out", rerender=False)
    corrected = load_rig(report["corrected_rig"])
    assert corrected.effects == ()
    # the file holds the fitted rig, and that is the rendered one: the projector's centre within 0.5 mm
    assert np.linalg.norm(corrected.projector.center - result.corrected_rig.projector.center) < 1e-6
    assert np.linalg.norm(corrected.projector.center - miscalibrated_rig(rig, params).projector.center) < 0.5


def test_camera_principal_point_is_told_from_the_projector(tmp_path, rig):
    """The stepwise fit alone (phase domain): a 1.5 px shift of the camera's principal point."""
    params = {"camera_principal_px": [1.5, 0.0]}
    measured = load_measured(_capture(tmp_path / "measured", rig, [{"calibration_error": params}], seed=4))
    reference = parse_reference(SPHERE)
    baseline = register_robust(rig, reference, measured.projector_x, erode_mask(measured.valid, 2),
                               period_px=measured.extent / measured.frequency)
    entry, fitted = fit_calibration_error(rig, reference, measured.projector_x, baseline)
    assert entry["evidence"]["components"][0] == "camera_cx_px"
    assert component_value(entry["parameters"], "camera_cx_px") == pytest.approx(1.5, rel=TOLERANCE)
    assert fitted.rms_px < 0.5 * baseline.rms_px


def test_clean_capture_of_the_outside_rig_names_none(tmp_path, rig):
    result = diagnose(_capture(tmp_path / "measured", rig, [], seed=5), rig, reference=SPHERE,
                      max_pixels=TEST_PIXELS)
    assert result.cause == "none"
    entry = next(e for e in result.effects if e["name"] == "calibration_error")
    assert not entry["named"] and entry["evidence"]["components"] == []
    assert result.corrected_rig is None
