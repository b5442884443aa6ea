"""What the outside captures of issue 17 confused, each hidden alone and required by name.

- A random per-frame flicker of the projector's brightness (``intensity_drift.sigma``) against sensor noise: the
  flicker is one gain per frame, shared by every pixel (tests/sim/diagnosis/hidden.py's nominal plane).
- Camera saturation (clips at one DN, so at a projected level that depends on each pixel's albedo and shading)
  against the projector's response (bends the projected level, the same for every pixel): both on a rig the
  project was not built on (tests/outside_rigs.py), on a sphere of another size and of a material the twin
  does not know.
- A step-scale error of the phase shifts (a ripple at twice the fringe frequency) against lens distortion
  (smooth over the image): on the nominal plane near the size at which the step error breaks the temporal
  unwrapping, and on an outside rig.
"""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.sim.diagnosis import diagnose
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.outside_rigs import outside_rig
from dptpu.sim.render import render_capture
from dptpu.sim.rig import load_twin_rig
from dptpu.sim.scene_mesh import Material
from dptpu.sim.scenes import load_scene
from dptpu.sim.scenes.builtin import plane_scene, sphere_scene

from .hidden import render_measured

TEST_PIXELS = 1000
SEQUENCES = [SequenceSpec(96, 12), SequenceSpec(1, 12)]
#: A material the twin's reference sphere does not have (the twin's: albedo 0.8, roughness 0.5, specular 0.1).
OTHER_MATERIAL = Material(albedo=0.6, roughness=0.4, specular=0.2, ior=1.5)
#: A projector that clips its own level at 0.75 of full scale (11 knots): a knee in the projected level.
KNEE = [round(min(k / 10, 0.75), 3) for k in range(11)]


def _entry(result, name):
    return next(e for e in result.effects if e["name"] == name)


def _summary(result):
    return [(e["name"], round(e["gain"], 3), e["named"]) for e in result.effects[:4]]


@pytest.mark.parametrize("seed, sigma", [(21, 0.01)])
def test_flicker_is_named_as_the_drift_s_random_gain_not_sensor_noise(tmp_path, seed, sigma):
    effect = {"intensity_drift": {"rate_per_frame": 0.0, "sigma": sigma}}
    folder, rig = render_measured(tmp_path / "measured", "plane", effect, seed=seed)
    result = diagnose(folder, rig, reference="plane", max_pixels=TEST_PIXELS)
    assert result.cause == "intensity_drift", _summary(result)
    entry = result.effects[0]
    assert not _entry(result, "sensor_noise")["named"]
    # the realization: the twin draws z_n for the 24 frames from the capture's seed, in frame order
    z = np.random.default_rng(seed).normal(size=24)
    gains = np.asarray(entry["evidence"]["frame_gains"])
    ratio = gains / (1.0 + sigma * z)
    assert np.std(ratio) / np.mean(ratio) < 0.05 * sigma  # each frame's gain to 5 % of the flicker
    realized = sigma * np.std(z, ddof=1)
    assert abs(entry["parameters"]["sigma"] - realized) < 0.05 * realized
    assert abs(entry["parameters"]["sigma"] - sigma) < 0.2 * sigma
    assert abs(entry["parameters"]["rate_per_frame"]) < sigma / 10  # no drift made up
    assert entry["gain"] > 0.5
    assert {"intensity_drift": entry["parameters"]} in result.extended_effects


def test_sensor_noise_is_not_taken_for_flicker(tmp_path):
    effect = {"sensor_noise": {"read_noise_dn": 2.0, "gain_dn_per_electron": 0.0}}
    folder, rig = render_measured(tmp_path / "measured", "plane", effect, seed=24)
    steps: list[str] = []
    result = diagnose(folder, rig, reference="plane", max_pixels=TEST_PIXELS, progress=steps.append)
    assert result.cause == "sensor_noise", _summary(result)
    # the progress the CLI shows: every step once, in the order they run
    assert steps[:3] == ["reading the data", "registering the reference", "lens_distortion"]
    assert {"saturation", "intensity_drift", "motion", "projector_response"} <= set(steps)
    assert steps[-1] == "sensor_noise" and len(steps) == len(set(steps))
    drift = _entry(result, "intensity_drift")
    assert drift["parameters"]["sigma"] == 0.0 and not drift["named"]
    assert drift["evidence"]["flicker_delta_bic_over_drift"] < 0


def _outside_sphere(tmp_path, effect, material=None):
    """A sphere of 40 mm on a rig the project was not built on (f = 1800 px, 150 mm, 14 deg), 160x120."""
    rig = outside_rig(camera_focal_px=1800.0, baseline_mm=150.0, angle_deg=14.0, size=(160, 120))
    folder = render_capture(rig, sphere_scene(rig, diameter_mm=40.0, material=material), SEQUENCES,
                            tmp_path / "measured", effects=[effect], seed=4)
    return diagnose(folder, rig, reference="sphere:40.0", max_pixels=TEST_PIXELS)


@pytest.mark.parametrize("material", [OTHER_MATERIAL], ids=["other_material"])
def test_camera_saturation_is_not_taken_for_the_projector_response(tmp_path, material):
    exposure_gain = 1.6 if material is None else 2.2
    result = _outside_sphere(tmp_path, {"saturation": {"exposure_gain": exposure_gain}}, material)
    assert result.cause == "saturation", _summary(result)
    entry = result.effects[0]
    assert not _entry(result, "projector_response")["named"]
    assert entry["parameters"]["level"] == pytest.approx(1.0, abs=0.01)  # the ADC's clip: full scale
    # exposure_gain is the data's brightness over the twin's surface: the hidden gain times the albedo ratio
    albedo_ratio = 1.0 if material is None else material.albedo / 0.8
    truth = exposure_gain * albedo_ratio
    assert abs(entry["parameters"]["exposure_gain"] - truth) <= 0.2 * (truth - 1.0)
    assert entry["gain"] > 0.9


@pytest.mark.parametrize("levels, material", [(None, OTHER_MATERIAL), (KNEE, OTHER_MATERIAL)],
                         ids=["s_curve_other_material", "knee_other_material"])
def test_projector_response_is_not_taken_for_camera_saturation(tmp_path, levels, material):
    """A knee in the projector's level flattens the fringe tops like a clip, but at the same projected level on
    every pixel, so at a DN proportional to the pixel's brightness: the table is named, not the clip."""
    effect = {"projector_response": {} if levels is None else {"levels": levels}}
    result = _outside_sphere(tmp_path, effect, material)
    assert result.cause == "projector_response", _summary(result)
    entry = result.effects[0]
    saturation = _entry(result, "saturation")
    assert saturation["gain"] < 0.5 * entry["gain"]
    assert entry["gain"] > 0.9
    if levels is not None:  # the knee comes back where it was hidden (the table's scale is the gain's business)
        fitted = np.asarray(entry["parameters"]["levels"])
        x = np.linspace(0.0, 1.0, fitted.size)
        knee_at = x[np.argmax(fitted >= fitted.max() - 1e-6)]
        assert 0.75 <= knee_at <= 0.75 + 2.0 / (fitted.size - 1)


def _nominal(tmp_path, scene, effects, seed):
    rig = load_twin_rig("nominal", size="160x120")
    folder = render_capture(rig, load_scene(scene, rig), SEQUENCES, tmp_path / "measured", effects=effects,
                            seed=seed)
    return diagnose(folder, rig, reference="plane" if scene == "plane" else "sphere:50.8082",
                    max_pixels=TEST_PIXELS)


@pytest.mark.parametrize("scene, scale, read_noise_dn", [("plane", 1.011, 1.0), ("sphere", 1.012, 0.0)])
def test_step_scale_error_at_the_mf_margin_is_not_taken_for_lens_distortion(tmp_path, scene, scale, read_noise_dn):
    """A 1.1-1.2 % step-scale error biases both phases by ~0.03 rad, 0.44-0.5 of an MF order at 96/1: the noise
    rounds regions (or the whole image) one order off. Decoded about the data's own MF centre, and with the one
    common order that registers best, the step error is named with its scale, not a smooth lens distortion."""
    effects = [{"phase_shift_error": {"scale": scale, "sigma_rad": 0.0}}]
    if read_noise_dn:
        effects.append({"sensor_noise": {"read_noise_dn": read_noise_dn, "gain_dn_per_electron": 0.0}})
    result = _nominal(tmp_path, scene, effects, seed=3)
    assert result.cause == "phase_shift_error", _summary(result)
    assert abs(result.effects[0]["parameters"]["scale"] - scale) <= 0.2 * abs(scale - 1.0)
    assert result.registration.rms_px < 0.05  # projector px: the twin's orders, no region a period off
    assert not _entry(result, "lens_distortion")["named"]


def test_lens_distortion_on_an_outside_rig_stays_lens_distortion(tmp_path):
    rig = outside_rig(camera_focal_px=1800.0, baseline_mm=150.0, angle_deg=14.0, size=(160, 120))
    folder = render_capture(rig, plane_scene(rig), SEQUENCES, tmp_path / "measured",
                            effects=[{"lens_distortion": {"camera": [-0.3, 0.0, 0.0, 0.0, 0.0]}}], seed=5)
    result = diagnose(folder, rig, reference="plane", max_pixels=TEST_PIXELS)
    assert result.cause == "lens_distortion", _summary(result)
    assert abs(result.effects[0]["parameters"]["camera"][0] + 0.3) <= 0.2 * 0.3
    assert not _entry(result, "phase_shift_error")["named"]
