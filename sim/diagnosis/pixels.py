"""The pixels a photometric fit uses, with what the twin knows about each (:class:`~.forward.PixelSet`).

- With a reference object (:func:`reference_pixels`): the registered surface gives each pixel's projector
  coordinate, normal and reflectance factor (:func:`dptpu.sim.image_formation.reflectance_factor`, the
  reference's material); pixels lit in the twin, one pixel in from the lit region's border (mixed pixels).
- Self-reference (:func:`self_reference_pixels`): no calibration, no object. Each sequence's own least-squares
  phase (Eq. (2); with 12 steps it is immune to harmonics up to the 10th, so a projector nonlinearity does not
  bias it) gives the projector coordinate modulo one period, and the mean level gives the reflectance factor
  (``a = FS R O``); the albedo (for ``ambient_light``) is taken proportional to that factor.

At most ``max_pixels`` pixels are kept (a seeded random subset): the fits are statistics over many pixels, and
their cost grows with the count.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from dptpu.fpp.phase import wrapped_phase
from dptpu.sim.image_formation import reflectance_factor

from .forward import ImageGrid, PixelSet
from .measured import Measured
from .reference import reference_hits, translated_pose

__all__ = ["reference_pixels", "self_reference_pixels", "motion_jacobian", "DEFAULT_MAX_PIXELS"]

DEFAULT_MAX_PIXELS = 12000
#: Self-reference: smallest modulation of a usable pixel, fraction of full scale.
MIN_MODULATION_FRACTION = 0.04


def erode_mask(mask: np.ndarray, pixels: int = 1) -> np.ndarray:
    """``mask`` (H, W) bool eroded by ``pixels`` (a square neighbourhood; outside the image counts as False)."""
    if pixels <= 0:
        return mask
    kernel = np.ones((2 * pixels + 1, 2 * pixels + 1), np.uint8)
    return cv2.erode(mask.astype(np.uint8), kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)


def _limit(mask: np.ndarray, max_pixels: int, seed: int) -> tuple:
    rows, cols = np.nonzero(mask)
    if len(rows) > max_pixels:
        keep = np.sort(np.random.default_rng(seed).choice(len(rows), max_pixels, replace=False))
        rows, cols = rows[keep], cols[keep]
    return rows, cols


@dataclass(frozen=True)
class _ReferenceSurface:
    """The registered reference's surface and material per pixel (H, W), as :func:`reflectance_factor` reads it."""

    points: np.ndarray
    normals: np.ndarray
    lit: np.ndarray
    albedo: np.ndarray
    roughness: np.ndarray
    specular: np.ndarray
    ior: np.ndarray


def _surface_material(hits, material, shape):
    """Per-pixel material arrays (H, W): a traced scene's own, or the analytic reference's uniform one."""
    if hits.samples is not None:
        samples = hits.samples
        return (samples.albedo.astype(np.float64), samples.roughness, samples.specular, samples.ior)
    return (np.full(shape, material.albedo), np.full(shape, material.roughness), np.full(shape, material.specular),
            np.full(shape, material.ior))


def motion_jacobian(rig, reference, pose, index, axis: int, coord, *, step=None) -> np.ndarray:
    """Derivative (P, 3) of the projector coordinate at pixels ``index`` with respect to a world translation
    of the reference (px per rig unit), by forward differences of :func:`~.reference.reference_hits` (step
    ``1e-4`` of the depth); 0 where a moved surface leaves the pixel."""
    hits = reference_hits(rig, reference, pose)
    depth = np.nanmedian(hits.points[..., 2][hits.lit]) if hits.lit.any() else 1.0
    step = 1e-4 * abs(float(depth)) if step is None else step
    columns = []
    for i in range(3):
        move = np.zeros(3)
        move[i] = step
        moved = reference_hits(rig, reference, translated_pose(rig, reference, pose, move))
        d = (moved.projector_xy[..., axis][index] - coord) / step
        ok = moved.lit[index] & np.isfinite(d)
        columns.append(np.where(ok, d, 0.0))
    return np.column_stack(columns)


def reference_pixels(measured: Measured, rig, reference, pose, material, *, max_pixels: int = DEFAULT_MAX_PIXELS,
                     seed: int = 0, erode_px: int = 1, index=None, motion: bool = True):
    """PixelSet of the registered reference surface (``rig`` may carry fitted geometry), and the lit mask (H, W).

    ``index`` ``(rows, cols)`` forces the pixels (to compare two geometries on the same values). The set carries
    the whole image (``grid``) and, with ``motion``, the coordinate's derivative with respect to a translation
    (:func:`motion_jacobian`; 6 more surface evaluations)."""
    hits = reference_hits(rig, reference, pose)
    axis = 0 if measured.fringe_axis == "x" else 1
    shape = hits.lit.shape
    albedo, roughness, specular, ior = _surface_material(hits, material, shape)
    samples = _ReferenceSurface(points=hits.points, normals=hits.normals, lit=hits.lit, albedo=albedo,
                                roughness=roughness, specular=specular, ior=ior)
    factor = np.where(hits.lit, reflectance_factor(rig, samples), 0.0)
    stack = np.concatenate(measured.frames)  # (sum N, H, W)
    mask = erode_mask(hits.lit, erode_px) & (factor > 0) & (stack.max(axis=0) > 0)
    rows, cols = _limit(mask, max_pixels, seed) if index is None else index
    coord_image = np.where(hits.lit, hits.projector_xy[..., axis], 0.0)
    coord = coord_image[rows, cols]
    grid = ImageGrid(coords=[coord_image] * len(measured.sequences), factor=factor,
                     albedo=np.where(hits.hit, albedo, 0.0), projector_depth=np.nan_to_num(hits.projector_depth),
                     hit=hits.hit)
    jacobian = motion_jacobian(rig, reference, pose, (rows, cols), axis, coord) if motion else None
    high = int(np.argmax([s.frequency for s in measured.sequences]))
    start = sum(s.steps for s in measured.sequences[:high])
    reference_frame = start + 0.5 * (measured.sequences[high].steps - 1)
    return PixelSet(index=(rows, cols), coords=[coord] * len(measured.sequences), factor=factor[rows, cols],
                    albedo=albedo[rows, cols], projector_depth=hits.projector_depth[rows, cols],
                    measured=[f[:, rows, cols] for f in measured.frames], sequences=list(measured.sequences),
                    extent=measured.extent, offset=measured.pattern.offset, amplitude=measured.pattern.amplitude,
                    full_scale=measured.full_scale, shape=shape, grid=grid, motion_jacobian=jacobian,
                    motion_reference_frame=reference_frame), mask


def self_reference_pixels(measured: Measured, *, max_pixels: int = DEFAULT_MAX_PIXELS, seed: int = 0):
    """PixelSet from the data alone (module docstring), and the usable mask (H, W)."""
    maps = [wrapped_phase(f, shift_sign=s.shift_sign, phase_offset=s.phase_offset)
            for f, s in zip(measured.frames, measured.sequences)]
    full_scale = measured.full_scale
    stack = np.concatenate(measured.frames)
    mask = np.ones(stack.shape[1:], dtype=bool)
    for m in maps:
        mask &= m.modulation > MIN_MODULATION_FRACTION * full_scale
    mask &= stack.min(axis=0) < full_scale  # a pixel at full scale in every frame holds no fringe
    mask = erode_mask(mask, 1)
    rows, cols = _limit(mask, max_pixels, seed)
    coords = [m.phase[rows, cols] * measured.extent / (2.0 * np.pi * s.frequency)
              for m, s in zip(maps, measured.sequences)]
    background = np.mean([m.background[rows, cols] for m in maps], axis=0)
    factor = background / (full_scale * measured.pattern.offset)
    return PixelSet(index=(rows, cols), coords=coords, factor=factor, albedo=factor.copy(),
                    projector_depth=np.zeros(len(rows)), measured=[f[:, rows, cols] for f in measured.frames],
                    sequences=list(measured.sequences), extent=measured.extent, offset=measured.pattern.offset,
                    amplitude=measured.pattern.amplitude, full_scale=full_scale, shape=mask.shape), mask
