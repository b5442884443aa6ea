"""Render the twin (and the extended twin) of the registered reference again, and decode it like the data.

The registered analytic surface (:func:`dptpu.sim.diagnosis.reference.surface_hits`) stands in for the
raycast trace (no facets): its points, normals, projector coordinates and visibility go through the twin's own
image formation, :func:`dptpu.sim.image_formation.render_frames_float`, with the effects given, and the frames
are quantized like a render (:func:`dptpu.sim.image_formation.quantize`). Decoding uses Eq. (2) and MF (a
1-period sequence present) or heterodyne unwrapping, as :func:`dptpu.sim.diagnosis.measured.load_measured` does.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from dptpu.fpp import tpu
from dptpu.fpp.fitting import fit_sphere
from dptpu.fpp.phase import wrapped_phase
from dptpu.fpp.reconstruct import DEFAULT_MIN_MODULATION_FRACTION
from dptpu.fpp.triangulate import Triangulator
from dptpu.sim.image_formation import quantize, render_frames_float

from .reference import surface_hits

__all__ = ["analytic_samples", "render_twin", "decode", "sphere_rms_um"]


def analytic_samples(rig, reference, pose, material):
    """A :class:`~dptpu.sim.raycast.SurfaceSamples`-like namespace of the analytic reference surface."""
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
                pattern=None) -> list[np.ndarray]:
    """Quantized frames (N, H, W) per sequence of the twin with ``effects``."""
    samples = analytic_samples(rig, reference, pose, material)
    kwargs = {} if pattern is None else {"offset": pattern.offset, "amplitude": pattern.amplitude}
    frames = render_frames_float(rig, samples, list(sequences), effects=list(effects), seed=seed,
                                 bit_depth=bit_depth, **kwargs)
    return [quantize(f, bit_depth).astype(np.float64) for f in frames]


def decode(frames, sequences, *, bit_depth: int = 8) -> np.ndarray:
    """Absolute phase (H, W) of the highest frequency, NaN where invalid (quality mask of every sequence)."""
    full_scale = float(2 ** bit_depth - 1)
    maps = [wrapped_phase(f, shift_sign=s.shift_sign, phase_offset=s.phase_offset) for f, s in zip(frames, sequences)]
    valid = np.ones(frames[0].shape[1:], dtype=bool)
    for f, m in zip(frames, maps):
        valid &= (m.modulation >= DEFAULT_MIN_MODULATION_FRACTION * full_scale) & (f.max(axis=0) < full_scale)
    order = np.argsort([-s.frequency for s in sequences])
    phases = [maps[i].phase for i in order]
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
