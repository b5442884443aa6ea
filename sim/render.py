"""Render a scene in the twin into a ``dptpu-capture/1`` folder: frames, ``calibration.yaml``, ``gt.npz``.

Engines: ``raycast`` (:mod:`dptpu.sim.raycast` + :mod:`dptpu.sim.image_formation`, the default) and ``blender``
(``dptpu.sim.blender.render_frames``, Cycles in a worker process): for Blender the pattern-stage effects act on
the projector images (:func:`dptpu.sim.effects.pattern.projector_images`), ``lens_distortion`` on the rig it
renders, and the camera-stage effects and the quantization on its float frames; ``motion`` and depth-dependent
projector defocus are raycast-only. Ground truth comes from the raycast trace in both cases.

``gt.npz`` keys (docs/capture-format.md, "Ground truth of twin renders"):

==================== ================== ===================================================================
key                  shape, dtype       meaning
==================== ================== ===================================================================
projector_x          (H, W) float32     projector column seen by each camera pixel (0-based), NaN invalid
projector_y          (H, W) float32     projector row, NaN invalid
depth                (H, W) float32     depth along the camera z axis, rig units, NaN where no surface
normals              (H, W, 3) float32  unit surface normals in world coordinates (towards the camera)
valid                (H, W) bool        surface hit AND lit by the projector (on its panel, not shadowed)
hit                  (H, W) bool        the camera ray hits a surface
fringe_order_<f>     (H, W) int32       ``floor(f * x_p / W_p)`` per phase-sequence frequency, -1 invalid
==================== ================== ===================================================================

``<f>`` is the frequency written with ``%g`` (``fringe_order_96``, ``fringe_order_10.9``), ``x_p`` the
coordinate along the sequence's fringe axis and ``W_p`` the projector extent along it.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from dptpu.fpp.calibration import Rig, save_rig
from dptpu.fpp.capture import PatternLevels, PhaseFrames, write_capture

from .effects import effects_to_yaml, find_effect, parse_effects
from .effects.camera import apply_camera_effects
from .effects.footprint import footprint_samples, integrate_footprint
from .effects.geometry import has_motion, render_rig
from .effects.pattern import projector_images
from .image_formation import DEFAULT_AMPLITUDE, DEFAULT_OFFSET, _as_sequences, quantize, render_frames_float
from .raycast import SurfaceSamples, trace
from .rig import resize_camera

__all__ = ["ENGINES", "ground_truth", "raycast_frames", "render_capture", "fringe_order_key"]

ENGINES = ("raycast", "blender")


def fringe_order_key(frequency: float) -> str:
    """``fringe_order_<f>`` with ``f`` written by ``%g``."""
    return f"fringe_order_{frequency:g}"


def ground_truth(rig: Rig, samples: SurfaceSamples, sequences) -> dict:
    """The ``gt.npz`` arrays (module docstring) of a trace."""
    valid = samples.lit.copy()
    projector_x = np.where(valid, samples.projector_xy[..., 0], np.nan).astype(np.float32)
    projector_y = np.where(valid, samples.projector_xy[..., 1], np.nan).astype(np.float32)
    gt = {"projector_x": projector_x, "projector_y": projector_y,
          "depth": np.where(samples.hit, samples.depth, np.nan).astype(np.float32),
          "normals": np.nan_to_num(samples.normals, nan=0.0).astype(np.float32),
          "valid": valid, "hit": samples.hit.copy()}
    for sequence in _as_sequences(sequences):
        if sequence.kind != "phase":
            continue
        axis = 0 if sequence.axis == "x" else 1
        extent = rig.projector.size[axis]
        coord = samples.projector_xy[..., axis]
        with np.errstate(invalid="ignore"):
            order = np.floor(sequence.frequency * coord / extent)
        gt[fringe_order_key(sequence.frequency)] = np.where(valid, order, -1).astype(np.int32)
    return gt


def _blender_frames(rig: Rig, meshes, sequences, effects, *, seed, bit_depth, exposure, samples_per_pixel, albedo,
                    hit):
    try:  # the Blender renderer is optional: an installation may lack it
        from dptpu.sim import blender  # optional
    except ModuleNotFoundError as exc:
        if exc.name != "dptpu.sim.blender":
            raise
        raise ValueError("engine 'blender' needs dptpu.sim.blender, which this installation lacks; "
                         "use engine='raycast'") from None

    if has_motion(effects):
        raise ValueError("the motion effect is raycast-only; use engine='raycast'")
    rng = np.random.default_rng(seed)
    full_scale = float(2 ** bit_depth - 1)
    out = []
    first_frame = 0
    for sequence in sequences:
        width, height = rig.projector.size
        if sequence.kind == "phase":
            patterns = projector_images(frequency=sequence.frequency, steps=sequence.steps, axis=sequence.axis,
                                        shift_sign=sequence.shift_sign, projector_size=rig.projector.size,
                                        offset=DEFAULT_OFFSET, amplitude=DEFAULT_AMPLITUDE,
                                        phase_offset=sequence.phase_offset, effects=effects, rng=rng)
        else:
            patterns = np.full((1, height, width), 1.0 if sequence.kind == "white" else 0.0)
        # frame n of the capture renders with Cycles seed seed + n: independent sampling noise in every frame
        linear = blender.render_frames(rig, meshes, patterns.astype(np.float32), samples=samples_per_pixel,
                                       seed=seed + first_frame)
        first_frame += len(patterns)
        frames = full_scale * exposure * np.asarray(linear, dtype=np.float64)
        out.append(apply_camera_effects(frames, effects=effects, albedo=albedo, hit=hit, full_scale=full_scale,
                                        exposure=exposure, rng=rng))
    return out


def _raycast_supersampled(rig: Rig, meshes, sequences, effects, base: SurfaceSamples, *, supersample: int, seed,
                          bit_depth, exposure) -> list[np.ndarray]:
    """Float frames at ``rig``'s size from ``supersample`` x ``supersample`` rays per pixel (a box filter: the
    pixel integrates its area); the camera-stage effects act on the binned frames, at the real pixels."""
    width, height = rig.camera.size
    footprint = find_effect(effects, "pixel_footprint")
    blur_sigma_px = 0.0 if footprint is None else footprint["blur_sigma_px"]
    fine_rig = resize_camera(rig, (width * supersample, height * supersample))
    fine = trace(fine_rig, meshes)
    optical = tuple(e for e in effects if e.stage != "camera")
    camera = tuple(e for e in effects if e.stage == "camera")
    rng = np.random.default_rng([seed, 1])
    full_scale = float(2 ** bit_depth - 1)
    out = []
    for sequence in sequences:  # one sequence at a time bounds the memory of the fine frames
        frames = render_frames_float(fine_rig, fine, [sequence], effects=optical, seed=seed, bit_depth=bit_depth,
                                     exposure=exposure)[0]
        binned = integrate_footprint(frames, supersample, blur_sigma_px)
        out.append(apply_camera_effects(binned, effects=camera, albedo=base.albedo.astype(np.float64), hit=base.hit,
                                        full_scale=full_scale, exposure=exposure, rng=rng))
    return out


def _raycast_float_frames(traced_rig: Rig, meshes, sequences, effects, samples: SurfaceSamples, *, supersample: int,
                          seed, bit_depth, exposure) -> list[np.ndarray]:
    """Float raycast frames of the traced rig: ``supersample`` rays per pixel and axis when above 1."""
    if supersample > 1:
        return _raycast_supersampled(traced_rig, meshes, sequences, effects, samples, supersample=supersample,
                                     seed=seed, bit_depth=bit_depth, exposure=exposure)
    return render_frames_float(traced_rig, samples, sequences, effects=effects, seed=seed, bit_depth=bit_depth,
                               exposure=exposure)


def raycast_frames(rig: Rig, meshes, sequences, *, seed: int = 0, bit_depth: int = 8,
                   exposure: float = 1.0) -> tuple[list[np.ndarray], SurfaceSamples]:
    """Quantized raycast frames of ``sequences`` with every effect of ``rig.effects``, as :func:`render_capture`
    renders them: the geometry stage included (``calibration_error`` and ``lens_distortion`` change the traced
    rig, ``pixel_footprint`` sets the rays per pixel), which :func:`dptpu.sim.image_formation.render_frames` alone
    does not apply.

    Parameters
    ----------
    rig : Rig
        The twin's rig; its ``effects`` are rendered.
    meshes : Scene or list of SceneMesh
    sequences : list of SequenceSpec
    seed, bit_depth, exposure
        As :func:`render_capture`'s; the same seed gives the same frames.

    Returns
    -------
    frames : list of ndarray (N, H, W)
        One quantized stack per sequence.
    samples : SurfaceSamples
        The pixel-centre trace of the rig the frames were traced with (their ground truth).
    """
    effects = parse_effects(rig.effects)
    meshes = meshes.meshes if hasattr(meshes, "meshes") else list(meshes)
    traced_rig = render_rig(rig, effects)
    samples = trace(traced_rig, meshes)
    frames = _raycast_float_frames(traced_rig, meshes, list(sequences), effects, samples,
                                   supersample=footprint_samples(effects), seed=seed, bit_depth=bit_depth,
                                   exposure=exposure)
    return [quantize(f, bit_depth) for f in frames], samples


def render_capture(rig: Rig, scene, sequences, out_dir, *, engine: str = "raycast", effects=None, seed: int = 0,
                   bit_depth: int = 8, exposure: float = 1.0, blender_samples: int = 16,
                   supersample: int = 1) -> Path:
    """Render ``scene`` in the twin of ``rig`` and write a ``dptpu-capture/1`` folder.

    Parameters
    ----------
    rig : Rig
        The twin's rig; written as ``calibration.yaml`` (with the effects used in its ``effects:`` list).
    scene : Scene or list of SceneMesh
    sequences : list of SequenceSpec
        Phase sequences (all on one fringe axis, one shift sign) and optional ``white``/``black`` frames, which
        become the capture's ``references``.
    out_dir : path-like
        Folder to write (created).
    engine : {"raycast", "blender"}
    effects : list, optional
        Effects (entries or parsed); default ``rig.effects``.
    seed : int
        Seed of noise and random effects.
    bit_depth : {8, 16}
    exposure : float
        See :func:`dptpu.sim.image_formation.render_frames_float`.
    blender_samples : int
        Cycles samples per pixel (engine ``blender``).
    supersample : int
        Raycast rays per pixel along each axis (1: one ray through the pixel centre). With ``s > 1`` the camera is
        traced at ``s`` times the resolution and each pixel averages its ``s x s`` rays (the sensor integrates its
        area: mixed pixels at depth edges and shadow borders); camera-stage effects act after the averaging. The
        ground truth stays the pixel-centre ray's.

    Returns
    -------
    Path
        The capture folder.
    """
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}; got {engine!r}")
    sequences = _as_sequences(sequences)
    phase_sequences = [s for s in sequences if s.kind == "phase"]
    if not phase_sequences:
        raise ValueError("render_capture needs at least one phase sequence (e.g. 96x12)")
    axes = {s.axis for s in phase_sequences}
    signs = {s.shift_sign for s in phase_sequences}
    if len(axes) > 1 or len(signs) > 1:
        raise ValueError("a capture has one fringe_axis and one phase_shift_sign; render x and y sequences as "
                         f"separate captures (got axes {sorted(axes)}, signs {sorted(signs)})")
    kinds = [s.kind for s in sequences if s.kind != "phase"]
    if len(set(kinds)) != len(kinds):
        raise ValueError("at most one white and one black reference frame per capture")
    effects = parse_effects(rig.effects if effects is None else effects)
    meshes = scene.meshes if hasattr(scene, "meshes") else list(scene)
    traced_rig = render_rig(rig, effects)
    samples = trace(traced_rig, meshes)
    if find_effect(effects, "pixel_footprint") is not None:  # the effect's rays per pixel (docs/effects.md)
        supersample = max(int(supersample), footprint_samples(effects))
    if isinstance(supersample, bool) or not isinstance(supersample, int) or not 1 <= supersample <= 8:
        raise ValueError(f"supersample must be an integer in [1, 8]; got {supersample!r}")
    if supersample > 1 and engine != "raycast":
        raise ValueError("supersample applies to engine='raycast' (Blender samples with blender_samples)")
    if engine == "raycast":
        frames = _raycast_float_frames(traced_rig, meshes, sequences, effects, samples, supersample=supersample,
                                       seed=seed, bit_depth=bit_depth, exposure=exposure)
    else:
        frames = _blender_frames(traced_rig, meshes, sequences, effects, seed=seed, bit_depth=bit_depth,
                                 exposure=exposure, samples_per_pixel=blender_samples,
                                 albedo=samples.albedo.astype(np.float64), hit=samples.hit)
    frames = [quantize(f, bit_depth) for f in frames]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    calibration = save_rig(replace(rig, effects=tuple(effects_to_yaml(effects))), out_dir / "calibration.yaml")
    phase_frames = [PhaseFrames(images=f, frequency=s.frequency, phase_offset=s.phase_offset)
                    for s, f in zip(sequences, frames) if s.kind == "phase"]
    references = {s.kind: f[0] for s, f in zip(sequences, frames) if s.kind != "phase"}
    extras = {"twin": {"engine": engine, "seed": int(seed), "exposure": float(exposure), "supersample": supersample,
                       "scene": getattr(scene, "name", "meshes"), "scene_source": getattr(scene, "source", ""),
                       "effects": effects_to_yaml(effects)}}
    write_capture(out_dir, sequences=phase_frames, projector_size=rig.projector.size,
                  fringe_axis=phase_sequences[0].axis, phase_shift_sign=phase_sequences[0].shift_sign,
                  pattern=PatternLevels(DEFAULT_OFFSET, DEFAULT_AMPLITUDE), references=references or None,
                  calibration=calibration, ground_truth=ground_truth(traced_rig, samples, sequences),
                  ground_truth_name="gt.npz", extras=extras)
    return out_dir
