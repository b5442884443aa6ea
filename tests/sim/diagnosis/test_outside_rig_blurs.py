"""The blurs of issue 17 through the whole diagnosis, on phase files of rigs the project was not built on
(tests/outside_rigs.py: focal length, baseline, angle, projector panel and side drawn by the seed): a pixel
footprint, a camera blur after the sampling and a phase filter, each hidden alone in a sphere (half the field
wide) at a width drawn by the seed.

Required of ``diagnose`` (the frames are decoded, then dropped: a phase file): the hidden blur is THE cause, its
width within 20 %, and no geometric effect (``calibration_error``, ``lens_distortion``) is named beside it: the
blurs reach past the 2 px edge band into the pixels the geometry is fitted on, which the diagnosis must not read
as a calibration error (sim/diagnosis/blur_correction.py). The clean control of these captures is
tests/sim/diagnosis/test_hidden_calibration.py's.
"""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.sim.diagnosis import diagnose
from dptpu.sim.diagnosis.measured import load_measured
from dptpu.sim.diagnosis.rerender import decode
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.render import render_capture
from dptpu.sim.rig import working_point
from dptpu.sim.scenes.builtin import sphere_scene
from tests.outside_rigs import random_outside_rig

SEQUENCES = [SequenceSpec(96, 12), SequenceSpec(1, 12)]
#: The phase filter's captures: on these small images 96 periods lie 1.4-5.6 px apart, and a phasor filter a third
#: of a period wide averages the fringes away (the phasor mean falls by ``exp(-k^2 sigma^2 / 2)``, ``k`` the phase
#: gradient): 32 periods put them 4-17 px apart, as a real capture's are.
FILTER_SEQUENCES = [SequenceSpec(32, 12), SequenceSpec(1, 12)]
SIZE = (128, 96)
TOLERANCE = 0.2
#: Read noise under the phase filter (DN): the filter needs noise to show.
READ_NOISE_DN = 2.0


def _hidden(name: str, seed: int) -> tuple[list, str, float]:
    """The hidden effects, the main parameter's name and its value, the width drawn by ``seed``."""
    u = np.random.default_rng(seed).uniform()
    if name == "pixel_footprint":
        width = 0.6 + 0.5 * u
        return [{"pixel_footprint": {"samples": 4, "blur_sigma_px": width}}], "blur_sigma_px", width
    if name == "camera_defocus":
        width = 0.6 + 0.5 * u
        return [{"camera_defocus": {"sigma_px": width}}], "sigma_px", width
    width = 0.8 + 0.7 * u
    return ([{"sensor_noise": {"read_noise_dn": READ_NOISE_DN, "gain_dn_per_electron": 0.0, "dark_dn": 0.0}},
             {"phase_filter": {"sigma_px": width}}], "sigma_px", width)


def _phase_file(tmp_path, seed, effects, sequences=SEQUENCES):
    """A sphere half the field wide on the random rig of ``seed``, rendered with ``effects`` and decoded by the
    twin's decoder (:func:`dptpu.sim.diagnosis.rerender.decode`, the phase-stage ``phase_filter`` in it: the
    phase file of someone else's processing); the frames dropped."""
    rig = random_outside_rig(seed, size=SIZE)
    distance = float(np.linalg.norm(working_point(rig) - rig.camera.center))
    diameter = 0.5 * SIZE[0] / rig.camera.K[0, 0] * distance
    frame_effects = [e for e in effects if "phase_filter" not in e]
    folder = render_capture(rig, sphere_scene(rig, diameter_mm=diameter), sequences, tmp_path / "measured",
                            effects=frame_effects, seed=seed)
    measured = load_measured(folder)
    measured.absolute_phase = decode(measured.frames, measured.sequences, effects=effects)
    measured.frames = []
    return measured, rig, f"sphere:{diameter}"


@pytest.mark.parametrize("name, seed", [("pixel_footprint", 11), ("camera_defocus", 12), ("phase_filter", 15)])
def test_hidden_blur_is_the_cause_with_no_geometric_effect_beside_it(tmp_path, name, seed):
    effects, key, width = _hidden(name, seed)
    measured, rig, reference = _phase_file(tmp_path, seed, effects,
                                           FILTER_SEQUENCES if name == "phase_filter" else SEQUENCES)
    # the drift and step-error candidates (tests/sim/diagnosis/test_outside_rig_effects.py) left out: time
    result = diagnose(measured, rig, reference=reference, phase_candidates=False)
    summary = [(e["name"], e["parameters"].get(key), round(e["gain"], 3)) for e in result.named]
    assert result.cause == name, summary
    assert result.effects[0]["parameters"][key] == pytest.approx(width, rel=TOLERANCE), summary
    assert not {"calibration_error", "lens_distortion"} & {e["name"] for e in result.named}, summary
    assert result.corrected_rig is None
