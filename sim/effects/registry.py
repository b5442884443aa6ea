"""The effect vocabulary: names, stages, parameters and their validation.

An effect is switched on by an entry of a rig's ``effects:`` list (``Rig.effects``) or of an effects YAML file;
every effect is off unless listed. An entry is a bare name (default parameters), ``{name: NAME, PARAM: value}``
or ``{NAME: {PARAM: value}}``::

    effects:
      - projector_gamma: {gamma: 2.2}
      - {name: sensor_noise, read_noise_dn: 1.5}
      - vignetting

Stages (the order in which they act; docs/effects.md documents each effect's parameters and signature):

- ``pattern``: what the projector casts (levels, steps, pixels, focus), evaluated at the continuous projector
  coordinate;
- ``geometry``: where light goes (lens distortion absent from the calibration, object motion between frames);
- ``camera``: what the sensor records (ambient light, vignetting, blur, exposure drift, noise, saturation);
- ``phase``: inside the phase pipeline (smoothing of the wrapped phase); recorded with a capture, applied by
  decoders (:func:`dptpu.sim.effects.phase.phase_filter`), never to frames.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

__all__ = ["STAGES", "EFFECTS", "EffectSpec", "Effect", "parse_effects", "load_effects", "find_effect",
           "effects_to_yaml"]

STAGES = ("pattern", "geometry", "camera", "phase")
_KINDS = {"num": "a number", "pos": "a number > 0", "nonneg": "a number >= 0", "int0": "an integer >= 0",
          "vec2": "a list of 2 numbers", "vec3": "a list of 3 numbers", "vec5": "a list of 5 numbers (k1 k2 p1 p2 k3)",
          "list": "a list of numbers"}


@dataclass(frozen=True)
class EffectSpec:
    """One effect of the vocabulary: its stage, parameters ``{name: (kind, default)}`` and a one-line summary."""

    name: str
    stage: str
    parameters: dict
    summary: str


@dataclass(frozen=True)
class Effect:
    """An effect switched on, with all of its parameters (defaults filled in)."""

    name: str
    params: dict = field(default_factory=dict)

    @property
    def stage(self) -> str:
        return EFFECTS[self.name].stage

    def __getitem__(self, key):
        return self.params[key]

    def as_entry(self) -> dict:
        """The YAML entry ``{name: {params}}``."""
        return {self.name: {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.params.items()}}


#: Default ``projector_response``: an S-shaped response (smoothstep ``3p^2 - 2p^3``) at 11 knots.
DEFAULT_RESPONSE_LEVELS = tuple(round(3 * x * x - 2 * x ** 3, 6) for x in (k / 10 for k in range(11)))

_SPECS = [
    EffectSpec("phase_shift_error", "pattern", {"scale": ("num", 1.0), "errors_rad": ("list", []),
                                                 "sigma_rad": ("nonneg", 0.02)},
               "step n is shifted by scale*2*pi*n/N + errors_rad[n] + a seeded N(0, sigma_rad) error"),
    EffectSpec("projector_pixelation", "pattern", {"quantize_bits": ("int0", 8)},
               "the pattern is held constant over each micromirror (evaluated at the nearest projector pixel "
               "centre) and its level quantized to quantize_bits (0: not quantized)"),
    EffectSpec("projector_gamma", "pattern", {"gamma": ("pos", 2.2)},
               "projected level p -> p**gamma (intensity nonlinearity of the projector)"),
    EffectSpec("projector_response", "pattern", {"levels": ("list", list(DEFAULT_RESPONSE_LEVELS))},
               "projected level p -> a monotone piecewise-linear lookup table: levels[k] is the output at "
               "input k/(K-1) (K = len(levels) >= 2 knots evenly spaced on [0, 1])"),
    EffectSpec("projector_defocus", "pattern", {"sigma_px": ("nonneg", 1.0), "focus_distance": ("nonneg", 0.0),
                                                 "sigma_px_per_unit": ("nonneg", 0.0)},
               "Gaussian blur of the pattern along the fringe axis, sigma in projector pixels "
               "(sigma_px + sigma_px_per_unit * |projector depth - focus_distance| when focus_distance > 0)"),
    EffectSpec("lens_distortion", "geometry", {"camera": ("vec5", [0.0] * 5), "projector": ("vec5", [0.0] * 5)},
               "distortion coefficients added to the rig's in the render only (present in the data, absent "
               "from the calibration written with the capture)"),
    EffectSpec("calibration_error", "geometry",
               {"rotation_deg": ("vec3", [0.0, 0.0, 0.0]), "translation": ("vec3", [0.0, 0.0, 0.0]),
                "camera_focal_scale": ("pos", 1.0), "projector_focal_scale": ("pos", 1.0),
                "camera_principal_px": ("vec2", [0.0, 0.0]), "projector_principal_px": ("vec2", [0.0, 0.0])},
               "the rig the frames were taken with differs from the calibration written with them: the projector "
               "turned (rotation vector, deg) and moved (rig units) in its own frame, focal lengths scaled, "
               "principal points moved (px); render only"),
    EffectSpec("pixel_footprint", "geometry", {"samples": ("int0", 4), "blur_sigma_px": ("nonneg", 0.5)},
               "each camera pixel integrates the scene over its area (samples x samples rays) and a Gaussian lens "
               "blur of blur_sigma_px camera pixels; the camera-stage effects act after the integration"),
    EffectSpec("motion", "geometry", {"velocity_per_frame": ("vec3", [0.0, 0.0, 0.0]),
                                      "angular_deg_per_frame": ("vec3", [0.0, 0.0, 0.0])},
               "the scene moves rigidly between frames: frame g (0-based over the whole capture) is traced with "
               "the meshes rotated by g*angular (Euler xyz deg, about their centroid) and moved by g*velocity"),
    EffectSpec("ambient_light", "camera", {"level": ("nonneg", 0.05), "background": ("nonneg", 0.0)},
               "adds level*albedo of full scale on surfaces and background of full scale everywhere"),
    EffectSpec("vignetting", "camera", {"k1": ("num", -0.3), "k2": ("num", 0.0)},
               "frames multiplied by 1 + k1 r^2 + k2 r^4, r = distance to the image centre / half diagonal"),
    EffectSpec("camera_defocus", "camera", {"sigma_px": ("nonneg", 1.0)},
               "Gaussian blur of each frame, sigma in camera pixels (reflecting border)"),
    EffectSpec("intensity_drift", "camera", {"rate_per_frame": ("num", 0.01), "sigma": ("nonneg", 0.0)},
               "frame n of each sequence multiplied by (1 + rate_per_frame*n) * (1 + sigma*z_n), z_n ~ N(0,1) "
               "seeded"),
    EffectSpec("sensor_noise", "camera", {"read_noise_dn": ("nonneg", 1.0), "gain_dn_per_electron": ("nonneg", 0.05),
                                          "dark_dn": ("nonneg", 0.0)},
               "Poisson-Gaussian: gain*Poisson((signal+dark)/gain) + N(0, read_noise^2), in digital numbers"),
    EffectSpec("saturation", "camera", {"exposure_gain": ("pos", 1.5), "level": ("pos", 1.0)},
               "signal multiplied by exposure_gain, then clipped at level*full scale (full well)"),
    EffectSpec("phase_filter", "phase", {"sigma_px": ("pos", 1.0)},
               "Gaussian smoothing of the wrapped phase (on cos and sin, masked) before unwrapping"),
]
#: name -> EffectSpec, in the canonical order of application within each stage.
EFFECTS = {spec.name: spec for spec in _SPECS}


def _value(where: str, kind: str, value):
    expected = _KINDS[kind]
    if kind in ("num", "pos", "nonneg"):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value) or \
                (kind == "pos" and value <= 0) or (kind == "nonneg" and value < 0):
            raise ValueError(f"{where}: must be {expected}; got {value!r}")
        return float(value)
    if kind == "int0":
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
            raise ValueError(f"{where}: must be {expected}; got {value!r}")
        return int(value)
    size = {"vec2": 2, "vec3": 3, "vec5": 5}.get(kind)
    if not isinstance(value, (list, tuple)) or (size is not None and len(value) != size) or not all(
            isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        raise ValueError(f"{where}: must be {expected}; got {value!r}")
    return tuple(float(v) for v in value)


def _entry(entry, where: str) -> Effect:
    if isinstance(entry, Effect):
        return entry
    if isinstance(entry, str):
        name, params = entry, {}
    elif isinstance(entry, dict) and "name" in entry:
        name, params = entry["name"], {k: v for k, v in entry.items() if k != "name"}
    elif isinstance(entry, dict) and len(entry) == 1:
        name, params = next(iter(entry.items()))
        params = {} if params is None else params
        if not isinstance(params, dict):
            raise ValueError(f"{where}.{name}: parameters must be a mapping; got {params!r}")
    else:
        raise ValueError(f"{where}: an effect is a name, {{name: NAME, ...}} or {{NAME: {{...}}}}; got {entry!r}")
    if name not in EFFECTS:
        raise ValueError(f"{where}: unknown effect {name!r}; expected one of {', '.join(EFFECTS)}")
    spec = EFFECTS[name]
    unknown = sorted(set(params) - set(spec.parameters))
    if unknown:
        raise ValueError(f"{where}.{name}.{unknown[0]}: unknown parameter; {name} takes "
                         f"{', '.join(spec.parameters) or 'no parameters'}")
    values = {}
    for key, (kind, default) in spec.parameters.items():
        values[key] = _value(f"{where}.{name}.{key}", kind, params.get(key, default))
    if name == "pixel_footprint" and not 1 <= values["samples"] <= 8:
        raise ValueError(f"{where}.{name}.samples: must be an integer in [1, 8] (rays per pixel and axis); "
                         f"got {values['samples']!r}")
    if name == "projector_response":
        levels = np.asarray(values["levels"])
        if levels.size < 2 or np.any(levels < 0) or np.any(np.diff(levels) < 0):
            raise ValueError(f"{where}.{name}.levels: must be a non-decreasing list of >= 2 numbers >= 0 (the "
                             f"output at inputs evenly spaced on [0, 1]); got {[float(v) for v in levels]!r}")
    return Effect(name, values)


def parse_effects(entries, *, source: str = "effects") -> tuple[Effect, ...]:
    """Validated effects, in the canonical order of :data:`EFFECTS` (stage by stage).

    Raises
    ------
    ValueError
        An unknown effect or parameter, a value of the wrong kind, or an effect listed twice; the message names
        ``source``, the entry and what was expected.
    """
    if entries is None:
        return ()
    if isinstance(entries, (str, dict, Effect)):
        entries = [entries]
    if not isinstance(entries, (list, tuple)):
        raise ValueError(f"{source}: effects must be a list; got {type(entries).__name__}")
    parsed = [_entry(entry, f"{source}: effects[{i}]") for i, entry in enumerate(entries)]
    names = [e.name for e in parsed]
    for name in names:
        if names.count(name) > 1:
            raise ValueError(f"{source}: effect {name!r} is listed twice")
    order = list(EFFECTS)
    return tuple(sorted(parsed, key=lambda e: (STAGES.index(e.stage), order.index(e.name))))


def load_effects(path) -> tuple[Effect, ...]:
    """Effects from a YAML file holding ``effects: [...]`` (or a bare list)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such effects file")
    try:
        document = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({exc})") from None
    if isinstance(document, dict):
        unknown = sorted(set(document) - {"effects"})
        if unknown:
            raise ValueError(f"{path}: {unknown[0]}: unknown key; an effects file holds 'effects: [...]'")
        document = document.get("effects")
    if not isinstance(document, list):
        raise ValueError(f"{path}: effects: must be a list of effects; got {document!r}")
    return parse_effects(document, source=str(path))


def find_effect(effects, name: str) -> Effect | None:
    """The effect called ``name`` among ``effects`` (parsed), or None."""
    for effect in effects:
        if effect.name == name:
            return effect
    return None


def effects_to_yaml(effects) -> list:
    """Parsed effects as a YAML-ready list of ``{name: {params}}``."""
    return [effect.as_entry() for effect in effects]
