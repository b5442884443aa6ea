"""pixel_footprint: the integration over a pixel's area and the lens blur (analytic), and the effect hidden in a
phase file from an outside rig (sim/outside_rigs.py), found on the edge band with its blur within 20 % and
told from camera_defocus (the clean control of the same rig: tests/sim/diagnosis/test_hidden_calibration.py)."""
import numpy as np
import pytest

from dptpu.sim.diagnosis.footprint_fit import fit_pixel_footprint
from dptpu.sim.diagnosis.measured import load_measured
from dptpu.sim.diagnosis.pixels import erode_mask
from dptpu.sim.diagnosis.reference import parse_reference
from dptpu.sim.diagnosis.registration import register_robust
from dptpu.sim.effects import parse_effects
from dptpu.sim.effects.footprint import integrate_footprint
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.outside_rigs import outside_rig
from dptpu.sim.render import render_capture
from dptpu.sim.scenes import load_scene

SEQUENCES = [SequenceSpec(96, 12), SequenceSpec(1, 12)]


def test_a_pixel_half_over_an_edge_holds_half_the_light():
    fine = np.zeros((1, 8, 8))
    fine[:, :, :6] = 100.0  # the edge at 6 fine samples: the second pixel (samples 4-7) is half covered
    pixels = integrate_footprint(fine, 4, 0.0)
    np.testing.assert_allclose(pixels[0], [[100.0, 50.0], [100.0, 50.0]])
    # the blur moves light, it does not create or lose it (reflecting borders, a symmetric scene)
    blurred = integrate_footprint(np.ones((2, 16, 16)) * 7.0, 4, 0.8)
    np.testing.assert_allclose(blurred, 7.0)


def test_samples_are_validated():
    with pytest.raises(ValueError, match=r"pixel_footprint.samples: must be an integer in \[1, 8\]"):
        parse_effects([{"pixel_footprint": {"samples": 0}}])


@pytest.fixture(scope="module")
def rig():
    return outside_rig(camera_focal_px=1800.0, baseline_mm=150.0, angle_deg=12.0, size=(160, 120))


def _fit(folder, rig, effects):
    render_capture(rig, load_scene("sphere", rig), SEQUENCES, folder, effects=effects, seed=3)
    measured = load_measured(folder)
    measured.frames = []  # a phase file: the decoded phase alone
    reference = parse_reference("sphere:50.8082")
    registration = register_robust(rig, reference, measured.projector_x, erode_mask(measured.valid, 2),
                                   period_px=measured.extent / measured.frequency)
    material = load_scene("sphere", rig).meshes[0].material
    return fit_pixel_footprint(measured, registration, reference, material)


def test_hidden_footprint_is_found_on_the_edge_band(tmp_path, rig):
    entry = _fit(tmp_path / "footprint", rig, [{"pixel_footprint": {"samples": 4, "blur_sigma_px": 0.8}}])
    assert entry["parameters"]["blur_sigma_px"] == pytest.approx(0.8, rel=0.2)
    assert entry["gain"] > 0.3 and entry["evidence"]["delta_bic"] > 10
    assert entry["evidence"]["beats_alternatives"], entry["evidence"]["alternatives"]

