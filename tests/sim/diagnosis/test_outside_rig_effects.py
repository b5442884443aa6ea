"""Hidden effects on rigs the project was not built on (issue 17): every effect of the vocabulary, two at once,
and clean controls, on random rigs (tests/outside_rigs.py: focal length, baseline, angle and projector panel
drawn by the seed) at small random sizes.

The diagnosis gets the frames and the rig only. Required: the hidden effect is the cause with its main parameter
within 20 % (tests/sim/diagnosis/hidden.py's measure); two effects are both named, the larger (by gain) as the
cause and the other in the next round, each within 20 %; with no effect the cause is "none".
"""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.sim.diagnosis import diagnose
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.outside_rigs import random_outside_rig
from dptpu.sim.render import render_capture
from dptpu.sim.rig import working_point
from dptpu.sim.scenes.builtin import plane_scene, sphere_scene

from .hidden import MAIN, hidden_effect, relative_error

TEST_PIXELS = 800
SEQUENCES = [SequenceSpec(96, 12), SequenceSpec(1, 12)]
SIZES = ((120, 90), (128, 96), (160, 120))
#: The vocabulary of hidden.py and the drift's random part, the flicker (its main parameter: sigma).
VOCABULARY = [*MAIN, "flicker"]


def _capture(tmp_path, seed, effects, *, size=None, sphere=False):
    """A capture of a plane (or a sphere half as wide as the field) on the random rig of ``seed``."""
    rng = np.random.default_rng(seed)
    size = size or SIZES[int(rng.integers(len(SIZES)))]
    rig = random_outside_rig(seed, size=size)
    if sphere:
        distance = float(np.linalg.norm(working_point(rig) - rig.camera.center))
        diameter = 0.5 * size[0] / rig.camera.K[0, 0] * distance
        scene, reference = sphere_scene(rig, diameter_mm=diameter), f"sphere:{diameter}"
    else:
        scene, reference = plane_scene(rig), "plane"
    folder = render_capture(rig, scene, SEQUENCES, tmp_path / "measured", effects=effects, seed=seed)
    return folder, rig, reference, scene


def _effect(name, seed, tmp_path):
    """The hidden effect of ``name`` sized by ``seed`` (hidden.py's plane sizes); saturation past the gain at which
    this rig's brightest pixel reaches full scale, measured on its clean render."""
    if name == "flicker":
        u = np.random.default_rng(seed).uniform(0.6, 1.0)
        return {"intensity_drift": {"rate_per_frame": 0.0, "sigma": 0.015 * u}}
    if name != "saturation":
        return hidden_effect(name, seed, 1.0, "plane")
    from dptpu.fpp.capture import load_sequence_images, read_capture

    folder, *_ = _capture(tmp_path / "clean", seed, [])
    capture = read_capture(folder)
    brightest = max(float(load_sequence_images(capture, s).max()) for s in capture.phase_sequences)
    u = np.random.default_rng(seed).uniform(0.6, 1.0)
    return {"saturation": {"exposure_gain": 255.0 / brightest * (1.0 + 0.4 * u)}}


def _error(name, true, fitted, seed=None):
    """hidden.py's relative error; the flicker's against the spread of its 24 draws, which the twin takes from the
    capture's seed in frame order when it is the only random effect (``seed``): a capture shows the draws, and
    their spread estimates ``sigma`` only to ``1 / sqrt(2 (F - 2))`` = 15 % (sim/diagnosis/flicker.py)."""
    if name == "flicker":
        realized = true["sigma"] * np.std(np.random.default_rng(seed).normal(size=24), ddof=1)
        return abs(fitted["sigma"] - realized) / realized
    return relative_error(name, true, fitted)


def _effect_name(name):
    return "intensity_drift" if name == "flicker" else name


@pytest.mark.parametrize("name", VOCABULARY)
def test_every_effect_is_named_and_sized_on_an_outside_rig(tmp_path, name):
    seed = 400 + VOCABULARY.index(name)
    effect = _effect(name, seed, tmp_path)
    folder, rig, reference, _ = _capture(tmp_path, seed, [effect], size=SIZES[0])
    result = diagnose(folder, rig, reference=reference, max_pixels=TEST_PIXELS)
    summary = [(e["name"], round(e["gain"], 3)) for e in result.effects[:3]]
    assert result.cause == _effect_name(name), summary
    entry = result.effects[0]
    assert _error(name, next(iter(effect.values())), entry["parameters"], seed) <= 0.2, (entry["parameters"], effect)
    assert entry["gain"] > 0


@pytest.mark.parametrize("seed, sphere", [(502, True)], ids=["sphere"])
def test_clean_capture_on_an_outside_rig_names_none(tmp_path, seed, sphere):
    folder, rig, reference, _ = _capture(tmp_path, seed, [], sphere=sphere, size=SIZES[0])
    result = diagnose(folder, rig, reference=reference, max_pixels=TEST_PIXELS)
    assert result.cause == "none", [(e["name"], round(e["gain"], 3)) for e in result.effects[:3]]
    assert result.extended_effects == []


@pytest.mark.parametrize("seed, larger, smaller", [
    (503, "projector_gamma", "intensity_drift"),
    (505, "projector_defocus", "flicker"),
])
def test_two_hidden_effects_are_both_named_in_order_of_size(tmp_path, seed, larger, smaller):
    sizes = {"projector_gamma": {"gamma": 1.8}, "intensity_drift": {"rate_per_frame": 0.002, "sigma": 0.0},
             "ambient_light": {"level": 0.25}, "phase_shift_error": {"scale": 1.005, "sigma_rad": 0.0},
             "projector_defocus": {"sigma_px": 1.5}, "flicker": {"rate_per_frame": 0.0, "sigma": 0.006}}
    effects = [{_effect_name(name): sizes[name]} for name in (larger, smaller)]
    folder, rig, reference, _ = _capture(tmp_path, seed, effects)
    steps: list[str] = []
    result = diagnose(folder, rig, reference=reference, max_pixels=TEST_PIXELS, rounds=2, progress=steps.append)
    assert result.cause == _effect_name(larger), [(e["name"], round(e["gain"], 3)) for e in result.effects[:3]]
    assert [e["name"] for e in result.additional] == [_effect_name(smaller)]
    # the second round's progress (dptpu twin diagnose's bar): one step per candidate fitted on top of the cause
    on_top = f" on top of {_effect_name(larger)}"
    fitted = [s.removeprefix("round 2: ").removesuffix(on_top) for s in steps
              if s.startswith("round 2: ") and s.endswith(on_top)]
    assert fitted[0] == "effects" and _effect_name(smaller) in fitted and _effect_name(larger) not in fitted
    assert len(fitted) == len(set(fitted)) >= 5
    first, second = result.effects[0], result.additional[0]
    assert first["gain"] > second["gain"] > 0.05
    assert _error(larger, sizes[larger], first["parameters"]) <= 0.2
    assert _error(smaller, sizes[smaller], second["parameters"], seed) <= 0.2
    assert [next(iter(e)) for e in result.extended_effects] == [_effect_name(larger), _effect_name(smaller)]
