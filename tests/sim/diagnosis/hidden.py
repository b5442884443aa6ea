"""Hidden-effect fixtures: "measured" captures of the standard sphere and a plane rendered by the twin with
exactly one effect switched on, chosen and sized by a seed (``numpy.random.default_rng(seed)``): the 8 effects the
issue requires and the twin's grid and motion effects (vignetting, camera_defocus, projector_pixelation, motion).

The diagnosis sees only the frames (the capture declares the projected pattern's offset and amplitude, as the
capture format allows) and the baseline rig. ``MAIN`` names each effect's main parameter and how it is compared:
the relative error of the value itself, or of its departure from "no effect" (``scale - 1``), within
``TOLERANCE`` (docs/sim-to-real.md).
"""
from __future__ import annotations

import numpy as np

from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.render import render_capture
from dptpu.sim.rig import load_twin_rig
from dptpu.sim.scenes import load_scene

SIZE = "160x120"
SEQUENCES = (SequenceSpec(96, 12), SequenceSpec(1, 12))
REFERENCES = {"sphere": "sphere:50.8082", "plane": "plane"}

#: Exposure gain at which the brightest pixel of the noiseless render reaches full scale (255 / max level:
#: plane 196 DN, sphere 212 DN); saturation does nothing below it.
CLIP_ONSET_GAIN = {"plane": 255.0 / 196.0, "sphere": 255.0 / 212.0}

#: effect -> (main parameter, neutral value the error is measured from, relative tolerance)
MAIN = {
    "projector_gamma": ("gamma", 1.0, 0.2),
    "projector_defocus": ("sigma_px", 0.0, 0.2),
    "lens_distortion": ("camera", 0.0, 0.2),
    "ambient_light": ("level", 0.0, 0.2),
    "sensor_noise": ("read_noise_dn", 0.0, 0.2),
    "intensity_drift": ("rate_per_frame", 0.0, 0.2),
    "phase_shift_error": ("scale", 1.0, 0.2),
    "saturation": ("exposure_gain", 1.0, 0.2),
    "vignetting": ("k1", 0.0, 0.2),
    "camera_defocus": ("sigma_px", 0.0, 0.2),
    "projector_pixelation": ("quantize_bits", None, 0.0),  # a discrete parameter: exactly the hidden value
    "motion": ("velocity_per_frame", 0.0, 0.2),  # |fitted - true| / |true| of the velocity vector
}


def hidden_effect(name: str, seed: int, magnitude: float = 1.0, scene: str = "plane") -> dict:
    """The effect entry ``{name: {params}}`` of ``name`` sized by ``seed``; ``magnitude`` scales its departure
    from "no effect" (1: the typical range; 0.2: a small one)."""
    rng = np.random.default_rng(seed)
    sign = rng.choice([-1.0, 1.0])
    u = rng.uniform(0.6, 1.0) * magnitude
    if name == "projector_gamma":
        return {name: {"gamma": 1.0 + 1.2 * u}}
    if name == "projector_defocus":
        return {name: {"sigma_px": 2.0 * u}}
    if name == "lens_distortion":  # the sphere covers the middle of the image only: it needs a larger k1
        k1 = sign * (0.6 if scene == "plane" else 8.0) * u
        return {name: {"camera": [k1, 0.0, 0.0, 0.0, 0.0]}}
    if name == "ambient_light":
        return {name: {"level": 0.3 * u}}
    if name == "sensor_noise":
        return {name: {"read_noise_dn": 3.0 * u, "gain_dn_per_electron": 0.0}}
    if name == "intensity_drift":
        return {name: {"rate_per_frame": sign * 0.004 * u, "sigma": 0.0}}
    if name == "phase_shift_error":
        return {name: {"scale": 1.0 + sign * 0.008 * u, "sigma_rad": 0.0}}
    if name == "saturation":  # sized past the gain at which the brightest pixel starts to clip
        return {name: {"exposure_gain": CLIP_ONSET_GAIN[scene] * (1.0 + 0.4 * u)}}
    if name == "vignetting":  # the sphere covers the middle of the image only: it needs a larger k1
        return {name: {"k1": -(0.3 if scene == "plane" else 0.5) * u, "k2": 0.0}}
    if name == "camera_defocus":  # below ~0.3 px the twin's blur changes no pixel (neighbour weight 4e-6 at 0.2)
        return {name: {"sigma_px": 0.3 + 0.5 * u}}
    if name == "projector_pixelation":  # no size: the staircase is one projector pixel; the level bits vary
        return {name: {"quantize_bits": int(rng.choice([0, 5, 6]))}}
    if name == "motion":  # mostly along the camera axis (a sphere sliding sideways barely changes a pixel's view)
        direction = np.array([0.0, 0.0, 1.0]) if scene == "plane" else np.array([*rng.uniform(-0.3, 0.3, 2), 1.0])
        return {name: {"velocity_per_frame": (sign * 0.03 * u * direction).tolist(),
                       "angular_deg_per_frame": [0.0, 0.0, 0.0]}}
    raise ValueError(f"no hidden-effect recipe for {name!r}")


def main_value(name: str, parameters: dict):
    value = parameters[MAIN[name][0]]
    if name == "motion":
        return np.asarray(value, dtype=np.float64)
    return float(value[0] if isinstance(value, (list, tuple)) else value)


def relative_error(name: str, true: dict, fitted: dict) -> float:
    """``|fitted - true| / |true - neutral|`` of the main parameter (a vector: its norm; a discrete parameter:
    0 when equal, 1 otherwise)."""
    neutral = MAIN[name][1]
    t, f = main_value(name, true), main_value(name, fitted)
    if neutral is None:
        return 0.0 if f == t else 1.0
    return float(np.linalg.norm(f - t) / np.linalg.norm(t - neutral))


def render_measured(folder, scene: str, effect=None, *, seed: int = 0):
    """Render the 'measured' capture (96x12 + 1x12, 160x120, nominal rig) and return ``(folder, baseline rig)``."""
    rig = load_twin_rig("nominal", size=SIZE)
    render_capture(rig, load_scene(scene, rig), list(SEQUENCES), folder, effects=[effect] if effect else [],
                   seed=seed)
    return folder, rig
