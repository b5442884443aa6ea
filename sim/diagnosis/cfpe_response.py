"""The CFPE projector's response as a twin effect: a ``projector_gamma`` whose 3-step phase error is the real one.

The real CFPE 3-step phases (steps 0, 4, 8 of each 12-step sequence) differ from the 12-step phases of the same
frames by ``b sin(3 psi)`` with ``b = -0.145 .. -0.167`` rad (:func:`.cfpe_inputs.cfpe_phase_error`, per scene;
what is left is 0.03 rad RMS of noise): the projector's response, a property of the projector and its pattern
levels, not of the scene (:mod:`dptpu.fpp.phase_harmonics`). A twin that is to teach a network to read through it
must render the same error. A response bends the projected level ``p = offset + amplitude cos(theta)`` the same
way at every pixel, so its phase error is an even function of ``theta`` and carries ``sin(3 psi)`` alone; a power
law ``p -> p^gamma`` makes ``b`` fall monotonically with ``gamma`` (0 at ``gamma = 1``), so one number, ``gamma``,
matches the one number the 3-step phase sees.

:func:`matched_gamma` solves ``gamma`` by bisection on the twin's own pattern stage
(:func:`dptpu.sim.effects.pattern.pattern_levels`) at the design's levels; :func:`rendered_phase_error` checks it
on a ray-cast twin scene (the whole render: geometry, albedo, projector pixels, 8-bit frames), where the fit of
:func:`dptpu.fpp.phase_harmonics.fit_harmonic_phase_error` must return the real ``b``.

Not modelled: a camera saturation that clips at a level depending on each pixel's albedo. It makes the phase error
depend on the pixel (and a clip's error has the opposite sign: ``+0.32`` rad for a gain of 1.68 on a white pixel),
while the real error is the same on every scene within 0.02 rad, and the CFPE inputs drop saturated pixels.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from dptpu.fpp import phase
from dptpu.fpp.phase_harmonics import HarmonicPhaseError, fit_harmonic_phase_error
from dptpu.fpp.rig_model import DeviceModel, Rig
from dptpu.sim.effects import parse_effects
from dptpu.sim.effects.pattern import pattern_levels
from dptpu.sim.image_formation import SequenceSpec, quantize, render_frames_float
from dptpu.sim.raycast import trace
from dptpu.sim.scenes import random_scene

from .cfpe_inputs import INPUT_STEPS, PROJECTOR_WIDTH_PX, SHIFT_SIGN, cfpe_phase_error

__all__ = ["GAMMA_RANGE", "COVERAGE_MARGIN", "pattern_phase_error", "matched_gamma", "cfpe_response_effects",
           "rendered_phase_error", "cfpe_twin_rig"]

#: Bracket of the bisection of :func:`matched_gamma`: a 3-step error of either sign up to ~0.45 rad at CFPE's levels.
GAMMA_RANGE = (0.2, 5.0)
#: Levels of CFPE's patterns (its README): ``128 + 96 cos(.)`` of 255.
CFPE_OFFSET = 128 / 255
CFPE_AMPLITUDE = 96 / 255
#: The CFPE twin camera's horizontal field of view over the projector's (tangents of the half angles).
COVERAGE_MARGIN = 1.15
_RENDER_STEPS = 12
_SAMPLES = 4096
_BISECTION_STEPS = 60
_TWO_PI = 2.0 * np.pi


def cfpe_twin_rig(rig: Rig, margin: float = COVERAGE_MARGIN) -> Rig:
    """``rig`` with a camera that sees the projector's whole width, as CFPE's does.

    The CFPE camera sees the projected fringes from one end of the projector to the other (the 12-step reference
    phase spans 2.5-100 % of the projector's width on every scene), and the 3-step order's failures sit at fixed
    projector columns (the beat levels' rounding, a function of the projector coordinate alone). A twin whose
    camera sees only the middle of the projector (the nominal rig: 14 deg of camera against 29 deg of projector)
    never shows the network the other columns. The camera's focal lengths are scaled so that the tangent of its
    horizontal half angle is ``margin`` times the projector's (pixel size, principal point, pose kept); the
    projector, the pose and the effects are unchanged.
    """
    camera, projector = rig.camera, rig.projector
    tan_camera = 0.5 * camera.size[0] / camera.K[0, 0]
    tan_projector = 0.5 * projector.size[0] / projector.K[0, 0]
    scale = tan_camera / (float(margin) * tan_projector)
    if scale >= 1.0:
        return rig
    K = camera.K.copy()
    K[0, 0] *= scale
    K[0, 1] *= scale
    K[1, 1] *= scale
    return replace(rig, camera=DeviceModel(K=K, dist=camera.dist, R=camera.R, T=camera.T, size=camera.size))


def _fit(frames12: np.ndarray, mask: np.ndarray, shift_sign: int) -> HarmonicPhaseError:
    """The harmonic error of the 3-step phase (steps 0, 4, 8) against the 12-step phase of ``frames12`` (12, H, W)."""
    psi12 = phase.wrapped_phase(frames12, shift_sign=shift_sign).phase
    psi3 = phase.wrapped_phase(frames12[list(INPUT_STEPS)], shift_sign=shift_sign).phase
    return fit_harmonic_phase_error([psi3], [psi12], [mask], steps=len(INPUT_STEPS))


def pattern_phase_error(effects, *, offset: float = CFPE_OFFSET, amplitude: float = CFPE_AMPLITUDE,
                        shift_sign: int = SHIFT_SIGN) -> HarmonicPhaseError:
    """The 3-step phase's harmonic error that the twin's pattern stage alone gives (a linear camera, no noise).

    One period of the projected pattern (``_SAMPLES`` phases) through
    :func:`dptpu.sim.effects.pattern.pattern_levels` with ``effects`` (the pattern-stage ones act), 12 steps of
    ``shift_sign 2 pi n / 12``; steps 0, 4, 8 are the 3-step sequence, the 12 steps the reference.
    """
    parsed = parse_effects(effects)
    coord = np.arange(_SAMPLES, dtype=np.float64)[None, :]
    shifts = (shift_sign * _TWO_PI * np.arange(_RENDER_STEPS) / _RENDER_STEPS)[:, None]
    levels = pattern_levels(coord, frequency=1.0, extent=float(_SAMPLES), shift=shifts, offset=offset,
                            amplitude=amplitude, effects=parsed)  # (12, P)
    frames = levels[:, None, :]  # (12, 1, P)
    return _fit(frames, np.ones(frames.shape[1:], bool), shift_sign)


def matched_gamma(target: HarmonicPhaseError, *, offset: float = CFPE_OFFSET, amplitude: float = CFPE_AMPLITUDE,
                  shift_sign: int = SHIFT_SIGN) -> float:
    """The ``projector_gamma`` whose 3-step phase error (:func:`pattern_phase_error`) has ``target``'s ``sin``
    coefficient (the response's own direction; a pointwise response gives no ``cos`` term).

    Raises
    ------
    ValueError
        ``target`` is not a 3-step error, or its ``sin`` coefficient lies outside what :data:`GAMMA_RANGE` renders.
    """
    if target.steps != len(INPUT_STEPS):
        raise ValueError(f"matched_gamma takes a {len(INPUT_STEPS)}-step phase error; got {target.steps} steps")

    def error_of(gamma: float) -> float:
        return pattern_phase_error([{"projector_gamma": {"gamma": gamma}}], offset=offset, amplitude=amplitude,
                                   shift_sign=shift_sign).sin_rad

    low, high = GAMMA_RANGE
    at_low, at_high = error_of(low), error_of(high)
    if not min(at_low, at_high) <= target.sin_rad <= max(at_low, at_high):
        raise ValueError(f"a 3-step phase error of {target.sin_rad:.3g} rad x sin(3 psi) lies outside what a "
                         f"projector gamma in {list(GAMMA_RANGE)} renders ({at_low:.3g} .. {at_high:.3g} rad)")
    rising = at_high > at_low
    for _ in range(_BISECTION_STEPS):
        middle = 0.5 * (low + high)
        if (error_of(middle) < target.sin_rad) == rising:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def cfpe_response_effects(cfpe_dir, scenes) -> tuple[list[dict], HarmonicPhaseError]:
    """``(effects, measured)``: the twin effects of the CFPE projector's response, calibrated on ``scenes``.

    ``measured`` is the real 3-step harmonic phase error over ``scenes`` (:func:`.cfpe_inputs.cfpe_phase_error`);
    ``effects`` is ``[{"projector_gamma": {"gamma": matched_gamma(measured)}}]``, an effects list for an
    ``extended_effects.yaml`` (:func:`dptpu.experiments.downstream.split_rigs`).
    """
    measured = cfpe_phase_error(cfpe_dir, list(scenes))
    gamma = matched_gamma(measured)
    return [{"projector_gamma": {"gamma": round(float(gamma), 4)}}], measured


def rendered_phase_error(rig, effects, *, seed: int = 0, offset: float = CFPE_OFFSET,
                         amplitude: float = CFPE_AMPLITUDE, shift_sign: int = SHIFT_SIGN,
                         frequency: float = PROJECTOR_WIDTH_PX / 42) -> HarmonicPhaseError:
    """The 3-step harmonic phase error of a ray-cast twin scene rendered through ``rig`` with ``effects``.

    A random scene (:func:`dptpu.sim.scenes.random_scene` with ``seed``), one 12-step sequence of ``frequency``
    periods, noise-free 8-bit frames; fitted (3-step against 12-step phase) on the lit pixels whose 12-step
    modulation is at least 2 % of full scale and that no frame saturates. The check that the twin's renders carry
    the error :func:`matched_gamma` was solved for.
    """
    parsed = [e for e in parse_effects(effects) if e.name != "sensor_noise"]
    scene = random_scene(rig, seed)
    samples = trace(rig, scene.meshes)
    spec = SequenceSpec(float(frequency), _RENDER_STEPS, shift_sign=shift_sign)
    frames = quantize(render_frames_float(rig, samples, [spec], effects=parsed, seed=seed, offset=offset,
                                          amplitude=amplitude)[0], 8)
    maps = phase.wrapped_phase(frames, shift_sign=shift_sign)
    mask = samples.lit & phase.quality_mask(frames, maps.modulation, min_modulation=0.02 * 255)
    return _fit(frames, mask, shift_sign)
