"""The twin's image formation on a set of pixels, for fitting effects with the twin in the loop.

For pixel ``q`` with reflectance factor ``R_q`` (``lit * falloff * rho`` of
:func:`dptpu.sim.image_formation.reflectance_factor`, or a per-pixel level in self-reference), projector
coordinate ``c_q`` and albedo ``alpha_q``, step ``n`` of each sequence is rendered exactly as
:func:`dptpu.sim.image_formation.render_frames_float` does, through the twin's own effect stages
(:func:`dptpu.sim.effects.pattern.pattern_levels`, :func:`dptpu.sim.effects.camera.apply_camera_effects`)::

    I_n(q) = camera_effects( FS * R_q * p_n(c_q) )          (FS = 2^bit_depth - 1, exposure 1)

The pixels are a flat list (P,), so the camera-stage effects that need the image grid (``vignetting``,
``camera_defocus``) are not fitted here. A per-pixel gain ``s_q`` (albedo and exposure the twin does not know)
is fitted in closed form: ``s_q = sum_n I_n M_n / sum_n M_n^2`` over all frames of all sequences.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dptpu.sim.effects import parse_effects
from dptpu.sim.effects.camera import apply_camera_effects
from dptpu.sim.effects.pattern import defocus_sigma_px, pattern_levels, step_shifts

__all__ = ["PixelSet", "render_pixels", "fit_gain", "intensity_residual"]


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

    @property
    def size(self) -> int:
        return int(len(self.factor))

    @property
    def values(self) -> int:
        """Number of measured values (frames x pixels)."""
        return int(sum(m.size for m in self.measured))

    def subset(self, keep: np.ndarray) -> "PixelSet":
        """The pixels where ``keep`` (P,) is True."""
        return PixelSet(index=tuple(i[keep] for i in self.index), coords=[c[keep] for c in self.coords],
                        factor=self.factor[keep], albedo=self.albedo[keep],
                        projector_depth=self.projector_depth[keep], measured=[m[:, keep] for m in self.measured],
                        sequences=self.sequences, extent=self.extent, offset=self.offset,
                        amplitude=self.amplitude, full_scale=self.full_scale)


#: Step of the numerical derivative with respect to a sequence's phase offset, radians.
OFFSET_STEP_RAD = 1e-3


def render_pixels(pixels: PixelSet, effects=(), *, seed: int = 0, factor=None, offsets=None) -> list[np.ndarray]:
    """Model frames (N, P) float64 DN per sequence with ``effects`` (entries or parsed), before quantization;
    ``offsets`` (one per sequence, radians) are added to the sequences' phase offsets."""
    effects = parse_effects(effects)
    factor = pixels.factor if factor is None else factor
    rng = np.random.default_rng(seed)
    sigma = defocus_sigma_px(effects, pixels.projector_depth)
    hit = np.ones((pixels.size, 1), dtype=bool)
    out = []
    offsets = np.zeros(len(pixels.sequences)) if offsets is None else offsets
    for sequence, coord, extra in zip(pixels.sequences, pixels.coords, offsets):
        shifts = step_shifts(sequence.steps, sequence.shift_sign, effects, rng)
        frames = np.empty((sequence.steps, pixels.size))
        for n in range(sequence.steps):
            frames[n] = pixels.full_scale * factor * pattern_levels(
                coord, frequency=sequence.frequency, extent=pixels.extent, shift=shifts[n], offset=pixels.offset,
                amplitude=pixels.amplitude, phase_offset=sequence.phase_offset + extra, effects=effects, sigma_px=sigma)
        frames = apply_camera_effects(frames[:, :, None], effects=effects, albedo=pixels.albedo[:, None], hit=hit,
                                      full_scale=pixels.full_scale, exposure=1.0, rng=rng)[:, :, 0]
        out.append(frames)
    return out


def fit_gain(measured: list, model: list) -> np.ndarray:
    """Per-pixel gain (P,) minimizing ``sum_n (I_n - s M_n)^2`` over all sequences."""
    numerator = sum((m * p).sum(axis=0) for m, p in zip(measured, model))
    denominator = sum((p * p).sum(axis=0) for p in model)
    return np.where(denominator > 0, numerator / np.maximum(denominator, 1e-12), 0.0)


def intensity_residual(pixels: PixelSet, effects=(), *, seed: int = 0, refine: int = 1, fit_offsets: bool = True):
    """Residual (measured - s_q model) per sequence, list of (N, P), the gain (P,) and the model frames.

    ``refine`` > 1 re-renders with the gain folded into the reflectance factor (so that levels reaching a
    clip or a nonlinearity are placed right) and fits the gain again. ``fit_offsets`` also fits one constant
    phase offset per sequence (a Gauss-Newton step on a numerical derivative): an effect that biases the
    measured phase by a constant (a step-scale error shifts the mean step) also biases the registered pose,
    and the offset gives that part back, so the effect is judged on what a pose cannot absorb.
    """
    factor = pixels.factor
    gain = np.ones(pixels.size)
    offsets = np.zeros(len(pixels.sequences))
    for _ in range(max(int(refine), 1)):
        model = render_pixels(pixels, effects, seed=seed, factor=factor, offsets=offsets)
        step = fit_gain(pixels.measured, model)
        if fit_offsets:
            shifted = render_pixels(pixels, effects, seed=seed, factor=factor, offsets=offsets + OFFSET_STEP_RAD)
            for s, (m, p0, p1) in enumerate(zip(pixels.measured, model, shifted)):
                derivative = step * (p1 - p0) / OFFSET_STEP_RAD  # (N, P)
                residual = m - step * p0
                denominator = float(np.sum(derivative * derivative))
                if denominator > 0:
                    offsets[s] += float(np.sum(residual * derivative)) / denominator
            model = render_pixels(pixels, effects, seed=seed, factor=factor, offsets=offsets)
            step = fit_gain(pixels.measured, model)
        gain = gain * step
        factor = factor * step
    model = [p * step for p in model]
    return [m - p for m, p in zip(pixels.measured, model)], gain, model
