"""The twin's image formation on a set of pixels, for fitting effects with the twin in the loop.

For pixel ``q`` with reflectance factor ``R_q`` (``lit * falloff * rho`` of
:func:`dptpu.sim.image_formation.reflectance_factor`, or a per-pixel level in self-reference), projector
coordinate ``c_q`` and albedo ``alpha_q``, step ``n`` of each sequence is rendered exactly as
:func:`dptpu.sim.image_formation.render_frames_float` does, through the twin's own effect stages
(:func:`dptpu.sim.effects.pattern.pattern_levels`, :func:`dptpu.sim.effects.camera.apply_camera_effects`)::

    I_n(q) = camera_effects( FS * R_q * p_n(c_q) )          (FS = 2^bit_depth - 1, exposure 1)

The pixels are a flat list (P,); the effects that need more than one value per pixel get it from the set:

- ``vignetting``: the factor at each pixel's image position (``shape`` and ``index``);
- ``camera_defocus``: the whole image is rendered from ``grid`` (every pixel of the registered reference: its
  projector coordinate, reflectance factor, albedo), blurred, and sampled at the pixels;
- ``motion`` (translation only): frame ``g`` (0-based over the sequences in order) sees each pixel's projector
  coordinate moved by ``(g - g_ref) J v`` with ``J`` (P, 3) = ``motion_jacobian``, the derivative of the
  coordinate with respect to a translation of the surface (a linearization: the displacement over a capture is
  a small fraction of the distance), ``g_ref`` the frame whose pose the registration found
  (``motion_reference_frame``: the middle of the highest-frequency sequence, whose phase was registered).

A gain ``s_q`` is fitted in closed form, per pixel (albedo and exposure the twin does not know:
``s_q = sum_n I_n M_n / sum_n M_n^2`` over all frames of all sequences) or, with ``per_pixel_gain=False``, one
for all pixels (the reference's uniform material is known: what varies across the image is then the twin's).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dptpu.sim.effects import find_effect, parse_effects
from dptpu.sim.effects.camera import apply_camera_effects, vignetting_factor
from dptpu.sim.effects.pattern import defocus_sigma_px, pattern_levels, step_shifts

__all__ = ["ImageGrid", "PixelSet", "render_pixels", "fit_gain", "fit_global_gain", "intensity_residual"]


@dataclass
class ImageGrid:
    """The whole image behind a :class:`PixelSet`, for ``camera_defocus``.

    Attributes
    ----------
    coords : list of ndarray (H, W)
        Projector coordinate along the fringe axis per sequence (projector px).
    factor, albedo, projector_depth : ndarray (H, W)
        As in :class:`PixelSet`, per image pixel; factor 0 off the reference.
    hit : ndarray (H, W) bool
        Pixels that see the reference.
    """

    coords: list[np.ndarray]
    factor: np.ndarray
    albedo: np.ndarray
    projector_depth: np.ndarray
    hit: np.ndarray


@dataclass
class PixelSet:
    """The pixels a photometric fit uses.

    Attributes
    ----------
    index : tuple of ndarray
        ``(rows, cols)`` of the P pixels in the image.
    coords : list of ndarray (P,)
        Projector coordinate along the fringe axis per sequence (projector px).
    factor : ndarray (P,)
        Reflectance factor: the frame of a projected level of 1, as a fraction of full scale.
    albedo : ndarray (P,)
    projector_depth : ndarray (P,)
    measured : list of ndarray (N, P)
        Measured frames per sequence, DN.
    sequences : list of SequenceSpec
    extent : float
        Projector extent along the fringe axis, px.
    offset, amplitude : float
        Declared pattern levels.
    full_scale : float
    shape : tuple (H, W), optional
        Image size (for ``vignetting``).
    grid : ImageGrid, optional
        The whole image for ``camera_defocus``.
    motion_jacobian : ndarray (P, 3), optional
        Derivative of the projector coordinate with respect to a translation of the surface (px per rig unit).
    motion_reference_frame : float
        Frame index (0-based over the sequences) of the registered pose.
    """

    index: tuple
    coords: list
    factor: np.ndarray
    albedo: np.ndarray
    projector_depth: np.ndarray
    measured: list
    sequences: list
    extent: float
    offset: float
    amplitude: float
    full_scale: float
    shape: tuple | None = None
    grid: ImageGrid | None = None
    motion_jacobian: np.ndarray | None = None
    motion_reference_frame: float = 0.0

    @property
    def size(self) -> int:
        return int(len(self.factor))

    @property
    def values(self) -> int:
        """Number of measured values (frames x pixels)."""
        return int(sum(m.size for m in self.measured))

    def subset(self, keep: np.ndarray) -> PixelSet:
        """The pixels where ``keep`` (P,) is True."""
        return PixelSet(index=tuple(i[keep] for i in self.index), coords=[c[keep] for c in self.coords],
                        factor=self.factor[keep], albedo=self.albedo[keep],
                        projector_depth=self.projector_depth[keep], measured=[m[:, keep] for m in self.measured],
                        sequences=self.sequences, extent=self.extent, offset=self.offset,
                        amplitude=self.amplitude, full_scale=self.full_scale, shape=self.shape, grid=self.grid,
                        motion_jacobian=None if self.motion_jacobian is None else self.motion_jacobian[keep],
                        motion_reference_frame=self.motion_reference_frame)


#: Step of the numerical derivative with respect to a sequence's phase offset, radians.
OFFSET_STEP_RAD = 1e-3


def _motion_velocity(effects):
    """Velocity (3,) of the ``motion`` effect, or None; angular motion is not modelled here."""
    effect = find_effect(effects, "motion")
    if effect is None:
        return None
    if any(effect["angular_deg_per_frame"]):
        raise ValueError("the diagnosis' forward model takes the motion effect's translation only "
                         "(angular_deg_per_frame must be [0, 0, 0])")
    return np.asarray(effect["velocity_per_frame"], dtype=np.float64)


def render_pixels(pixels: PixelSet, effects=(), *, seed: int = 0, factor=None, offsets=None) -> list[np.ndarray]:
    """Model frames (N, P) float64 DN per sequence with ``effects`` (entries or parsed), before quantization;
    ``offsets`` (one per sequence, radians) are added to the sequences' phase offsets."""
    effects = parse_effects(effects)
    factor = pixels.factor if factor is None else factor
    offsets = np.zeros(len(pixels.sequences)) if offsets is None else offsets
    blur = find_effect(effects, "camera_defocus")
    if blur is not None and blur["sigma_px"] > 0:
        if pixels.grid is None:
            raise ValueError("camera_defocus needs the whole image of the reference (PixelSet.grid)")
        return _render_grid(pixels, pixels.grid, effects, seed=seed, factor=factor, offsets=offsets)
    rng = np.random.default_rng(seed)
    sigma = defocus_sigma_px(effects, pixels.projector_depth)
    hit = np.ones((pixels.size, 1), dtype=bool)
    vignetting = find_effect(effects, "vignetting")
    vignetting_map = None
    if vignetting is not None:
        if pixels.shape is None:
            raise ValueError("vignetting needs the pixels' image positions (PixelSet.shape)")
        vignetting_map = vignetting_factor(pixels.shape, vignetting["k1"], vignetting["k2"],
                                           rows=pixels.index[0], cols=pixels.index[1])[:, None]
    velocity = _motion_velocity(effects)
    if velocity is not None and pixels.motion_jacobian is None:
        raise ValueError("motion needs the projector coordinate's derivative (PixelSet.motion_jacobian)")
    step = None if velocity is None else pixels.motion_jacobian @ velocity  # (P,) px per frame
    out, frame = [], 0
    for sequence, coord, extra in zip(pixels.sequences, pixels.coords, offsets):
        shifts = step_shifts(sequence.steps, sequence.shift_sign, effects, rng)[:, None]  # (N, 1)
        c = coord[None, :]
        if step is not None:
            frames_index = frame + np.arange(sequence.steps)[:, None] - pixels.motion_reference_frame
            c = c + frames_index * step[None, :]
        frame += sequence.steps
        frames = pixels.full_scale * factor * pattern_levels(
            c, frequency=sequence.frequency, extent=pixels.extent, shift=shifts, offset=pixels.offset,
            amplitude=pixels.amplitude, phase_offset=sequence.phase_offset + extra, effects=effects, sigma_px=sigma)
        frames = np.broadcast_to(frames, (sequence.steps, pixels.size))
        frames = apply_camera_effects(frames[:, :, None], effects=effects, albedo=pixels.albedo[:, None], hit=hit,
                                      full_scale=pixels.full_scale, exposure=1.0, rng=rng,
                                      vignetting_map=vignetting_map)[:, :, 0]
        out.append(frames)
    return out


def _render_grid(pixels: PixelSet, grid: ImageGrid, effects, *, seed: int, factor, offsets) -> list[np.ndarray]:
    """Render the whole image from ``grid`` (``pixels.grid``: effects on the image grid), sampled at the pixels;
    a ``factor`` other than the set's scales the sampled values (after the blur: an approximation)."""
    if _motion_velocity(effects) is not None:
        raise ValueError("camera_defocus and motion together are not modelled by the diagnosis")
    rng = np.random.default_rng(seed)
    rows, cols = pixels.index
    lit = grid.factor > 0
    sigma = defocus_sigma_px(effects, grid.projector_depth[lit])
    ratio = np.where(pixels.factor > 0, factor / np.where(pixels.factor > 0, pixels.factor, 1.0), 0.0)
    out = []
    for sequence, coord, extra in zip(pixels.sequences, grid.coords, offsets):
        shifts = step_shifts(sequence.steps, sequence.shift_sign, effects, rng)[:, None]  # (N, 1)
        frames = np.zeros((sequence.steps,) + grid.factor.shape)
        frames[:, lit] = pixels.full_scale * grid.factor[lit] * pattern_levels(
            coord[lit][None, :], frequency=sequence.frequency, extent=pixels.extent, shift=shifts,
            offset=pixels.offset, amplitude=pixels.amplitude, phase_offset=sequence.phase_offset + extra,
            effects=effects, sigma_px=sigma)
        frames = apply_camera_effects(frames, effects=effects, albedo=grid.albedo, hit=grid.hit,
                                      full_scale=pixels.full_scale, exposure=1.0, rng=rng)
        out.append(frames[:, rows, cols] * ratio[None, :])
    return out


def fit_gain(measured: list, model: list) -> np.ndarray:
    """Per-pixel gain (P,) minimizing ``sum_n (I_n - s M_n)^2`` over all sequences."""
    numerator = sum((m * p).sum(axis=0) for m, p in zip(measured, model))
    denominator = sum((p * p).sum(axis=0) for p in model)
    return np.where(denominator > 0, numerator / np.maximum(denominator, 1e-12), 0.0)


def fit_global_gain(measured: list, model: list) -> np.ndarray:
    """One gain for every pixel (returned as (P,)) minimizing ``sum (I - s M)^2`` over all values."""
    numerator = sum(float((m * p).sum()) for m, p in zip(measured, model))
    denominator = sum(float((p * p).sum()) for p in model)
    return np.full(model[0].shape[1], numerator / denominator if denominator > 0 else 0.0)


def intensity_residual(pixels: PixelSet, effects=(), *, seed: int = 0, refine: int = 1, fit_offsets: bool = True,
                       per_pixel_gain: bool = True):
    """Residual (measured - s_q model) per sequence, list of (N, P), the gain (P,) and the model frames.

    ``per_pixel_gain=False`` fits one gain for all pixels (:func:`fit_global_gain`).

    ``refine`` > 1 re-renders with the gain folded into the reflectance factor (so that levels reaching a
    clip or a nonlinearity are placed right) and fits the gain again. ``fit_offsets`` also fits one constant
    phase offset per sequence (a Gauss-Newton step on a numerical derivative): an effect that biases the
    measured phase by a constant (a step-scale error shifts the mean step) also biases the registered pose,
    and the offset gives that part back, so the effect is judged on what a pose cannot absorb.
    """
    gain_of = fit_gain if per_pixel_gain else fit_global_gain
    factor = pixels.factor
    gain = np.ones(pixels.size)
    offsets = np.zeros(len(pixels.sequences))
    for _ in range(max(int(refine), 1)):
        model = render_pixels(pixels, effects, seed=seed, factor=factor, offsets=offsets)
        step = gain_of(pixels.measured, model)
        if fit_offsets:
            shifted = render_pixels(pixels, effects, seed=seed, factor=factor, offsets=offsets + OFFSET_STEP_RAD)
            for s, (m, p0, p1) in enumerate(zip(pixels.measured, model, shifted)):
                derivative = step * (p1 - p0) / OFFSET_STEP_RAD  # (N, P)
                residual = m - step * p0
                denominator = float(np.sum(derivative * derivative))
                if denominator > 0:
                    offsets[s] += float(np.sum(residual * derivative)) / denominator
            model = render_pixels(pixels, effects, seed=seed, factor=factor, offsets=offsets)
            step = gain_of(pixels.measured, model)
        gain = gain * step
        factor = factor * step
    model = [p * step for p in model]
    return [m - p for m, p in zip(pixels.measured, model)], gain, model
