"""Render the twin (and the extended twin) of the registered reference again, and decode it like the data.

The registered analytic surface (:func:`dptpu.sim.diagnosis.reference.surface_hits`) stands in for the raycast trace (no
facets; a scene reference is traced at its registered pose): its points, normals, projector coordinates and visibility
go through the twin's own image formation, :func:`dptpu.sim.image_formation.render_frames_float`, with the effects
given, and the frames are quantized like a render (:func:`dptpu.sim.image_formation.quantize`). Decoding uses Eq. (2)
and MF (a 1-period sequence present) or heterodyne unwrapping, as :func:`dptpu.sim.diagnosis.measured.load_measured`
does.
"""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from dptpu.fpp import tpu
from dptpu.fpp.calibration import DeviceModel
from dptpu.fpp.fitting import fit_sphere
from dptpu.fpp.phase import wrapped_phase
from dptpu.fpp.reconstruct import DEFAULT_MIN_MODULATION_FRACTION
from dptpu.fpp.triangulate import Triangulator
from dptpu.sim.effects import find_effect, parse_effects
from dptpu.sim.effects.camera import apply_camera_effects
from dptpu.sim.effects.footprint import footprint_samples, integrate_footprint
from dptpu.sim.effects.geometry import has_motion
from dptpu.sim.effects.phase import apply_phase_effects
from dptpu.sim.image_formation import quantize, render_frames_float
from dptpu.sim.rig import resize_camera

from .reference import reference_hits, surface_hits, translated_pose

__all__ = ["analytic_samples", "render_twin", "render_footprint", "decode", "sphere_rms_um"]


def analytic_samples(rig, reference, pose, material):
    """A :class:`~dptpu.sim.raycast.SurfaceSamples`-like namespace of the analytic reference surface (a scene
    reference: the twin's ray cast of its meshes at ``pose``)."""
    if reference.kind == "scene":
        return reference_hits(rig, reference, pose).samples
    hits = surface_hits(rig, reference.kind, pose, diameter=reference.diameter)
    shape = hits.lit.shape
    nan3 = np.where(hits.hit[..., None], 1.0, np.nan)
    return SimpleNamespace(points=hits.points * nan3, normals=hits.normals * nan3, projector_xy=hits.projector_xy,
                           depth=np.where(hits.hit, hits.points[..., 2], np.nan), lit=hits.lit, hit=hits.hit,
                           albedo=np.where(hits.hit, material.albedo, 0.0).astype(np.float32),
                           roughness=np.full(shape, material.roughness, np.float32),
                           specular=np.full(shape, material.specular, np.float32),
                           ior=np.full(shape, material.ior, np.float32), mesh_index=np.where(hits.hit, 0, -1),
                           rig=rig, meshes=(), shape=shape)


def render_twin(rig, reference, pose, material, sequences, *, effects=(), seed: int = 0, bit_depth: int = 8,
                pattern=None, reference_frame: float = 0.0) -> list[np.ndarray]:
    """Quantized frames (N, H, W) per sequence of the twin with ``effects``.

    ``motion`` on an analytic reference (no meshes to move) renders frame ``g`` (0-based over the sequences)
    with the surface translated by ``(g - reference_frame) v``: ``pose`` is the pose at ``reference_frame``."""
    kwargs = {} if pattern is None else {"offset": pattern.offset, "amplitude": pattern.amplitude}
    parsed = parse_effects(list(effects))
    motion = find_effect(parsed, "motion")
    if motion is not None and reference.kind != "scene" and has_motion(parsed):
        return _render_moving(rig, reference, pose, material, list(sequences), parsed, motion, seed=seed,
                              bit_depth=bit_depth, reference_frame=reference_frame, **kwargs)
    if find_effect(parsed, "pixel_footprint") is not None:
        return render_footprint(rig, reference, pose, material, list(sequences), parsed, seed=seed,
                                bit_depth=bit_depth, **kwargs)
    samples = analytic_samples(rig, reference, pose, material)
    frames = render_frames_float(rig, samples, list(sequences), effects=parsed, seed=seed,
                                 bit_depth=bit_depth, **kwargs)
    return [quantize(f, bit_depth).astype(np.float64) for f in frames]


def _cropped_camera(rig, bounds):
    """``rig`` with its camera cut to ``bounds`` = (row0, row1, col0, col1): ``K``'s principal point moved."""
    r0, r1, c0, c1 = bounds
    camera = rig.camera
    K = camera.K.copy()
    K[0, 2] -= c0
    K[1, 2] -= r0
    return replace(rig, camera=DeviceModel(K=K, dist=camera.dist, R=camera.R, T=camera.T, size=(c1 - c0, r1 - r0)))


def render_footprint(rig, reference, pose, material, sequences, effects, *, seed: int = 0, bit_depth: int = 8,
                     **kwargs) -> list[np.ndarray]:
    """:func:`render_twin` with the ``pixel_footprint`` effect: the reference's part of the image (its bounding
    box and a margin for the blur) traced at ``samples x samples`` rays per pixel, integrated by
    :func:`dptpu.sim.effects.footprint.integrate_footprint`, then the camera-stage effects on the whole image."""
    effect = find_effect(effects, "pixel_footprint")
    if effect is None:
        raise ValueError("render_footprint renders the pixel_footprint effect; it is not among the effects")
    samples = footprint_samples(effects)
    base = analytic_samples(rig, reference, pose, material)
    width, height = rig.camera.size
    rows, cols = np.nonzero(base.hit)
    if rows.size == 0:
        raise ValueError(f"pixel_footprint: the reference {reference.label!r} is not in the image at this pose")
    margin = int(np.ceil(4.0 * effect["blur_sigma_px"])) + 2
    bounds = (max(rows.min() - margin, 0), min(rows.max() + margin + 1, height),
              max(cols.min() - margin, 0), min(cols.max() + margin + 1, width))
    crop = _cropped_camera(rig, bounds)
    fine_rig = resize_camera(crop, (crop.camera.size[0] * samples, crop.camera.size[1] * samples))
    fine = analytic_samples(fine_rig, reference, pose, material)
    optical = [e for e in effects if e.stage != "camera"]
    camera = [e for e in effects if e.stage == "camera"]
    rng = np.random.default_rng([seed, 1])
    full_scale = float(2 ** bit_depth - 1)
    out = []
    for sequence in sequences:  # one sequence at a time bounds the memory of the fine frames
        frames = render_frames_float(fine_rig, fine, [sequence], effects=optical, seed=seed, bit_depth=bit_depth,
                                     **kwargs)[0]
        whole = np.zeros((len(frames), height, width))
        whole[:, bounds[0]:bounds[1], bounds[2]:bounds[3]] = integrate_footprint(frames, samples,
                                                                                effect["blur_sigma_px"])
        whole = apply_camera_effects(whole, effects=camera, albedo=np.asarray(base.albedo, np.float64),
                                     hit=base.hit, full_scale=full_scale, exposure=1.0, rng=rng)
        out.append(quantize(whole, bit_depth).astype(np.float64))
    return out


def _render_moving(rig, reference, pose, material, sequences, effects, motion, *, seed, bit_depth,
                   reference_frame, **kwargs) -> list[np.ndarray]:
    """Frame by frame: each sequence rendered whole at each frame's pose, the frame of that step kept."""
    if any(motion["angular_deg_per_frame"]):
        raise ValueError("re-rendering an analytic reference takes the motion effect's translation only")
    still = [e for e in effects if e.name != "motion"]
    velocity = np.asarray(motion["velocity_per_frame"])
    out, g = [], 0
    for s, sequence in enumerate(sequences):
        frames = []  # step n of the sequence rendered at the pose of frame g
        for n in range(sequence.steps):
            moved = translated_pose(rig, reference, pose, (g - reference_frame) * velocity)
            samples = analytic_samples(rig, reference, moved, material)
            rendered = render_frames_float(rig, samples, [sequence], effects=still, seed=seed + s,
                                           bit_depth=bit_depth, **kwargs)[0]
            frames.append(rendered[n])
            g += 1
        out.append(quantize(np.stack(frames), bit_depth).astype(np.float64))
    return out


def decode(frames, sequences, *, bit_depth: int = 8, effects=()) -> np.ndarray:
    """Absolute phase (H, W) of the highest frequency, NaN where invalid (quality mask of every sequence); the
    phase-stage ``effects`` (``phase_filter``) act on each wrapped phase before the unwrapping."""
    full_scale = float(2 ** bit_depth - 1)
    maps = [wrapped_phase(f, shift_sign=s.shift_sign, phase_offset=s.phase_offset) for f, s in zip(frames, sequences)]
    valid = np.ones(frames[0].shape[1:], dtype=bool)
    for f, m in zip(frames, maps):
        valid &= (m.modulation >= DEFAULT_MIN_MODULATION_FRACTION * full_scale) & (f.max(axis=0) < full_scale)
    order = np.argsort([-s.frequency for s in sequences])
    phase_effects = [e for e in parse_effects(list(effects)) if e.stage == "phase"]
    phases = [apply_phase_effects(maps[i].phase, phase_effects, valid) for i in order]
    frequencies = [sequences[i].frequency for i in order]
    if len(phases) == 2 and abs(frequencies[1] - 1.0) < 1e-9:
        result = tpu.unwrap_mf(phases[0], phases[1], frequencies[0], 1.0, valid=valid)
    else:
        result = tpu.unwrap_heterodyne(phases, frequencies, valid=valid)
    phase = np.asarray(result.absolute_phase, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        ok = np.asarray(result.valid, bool) & valid & (phase >= 0) & (phase < 2 * np.pi * frequencies[0])
    return np.where(ok, phase, np.nan)


def sphere_rms_um(rig, projector_x: np.ndarray, mask: np.ndarray, *, axis: str = "x", mm_per_unit: float = 1.0):
    """Sphere-fit RMS (um, free radius, geometric fit) and radius of the triangulated ``projector_x`` on ``mask``."""
    valid = mask & np.isfinite(projector_x)
    points = Triangulator(rig, axis=axis).points(np.where(valid, projector_x, 0.0))[valid]
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) < 10:
        return float("nan"), float("nan")
    fit = fit_sphere(points)
    return float(fit.rms * 1e3 * mm_per_unit), float(fit.radius)
