"""Image formation of the fast twin: frames from surface samples and a pattern sequence.

For camera pixel ``q`` seeing surface point ``X`` (from :func:`dptpu.sim.raycast.trace`) and step ``n`` of a
sequence, in digital numbers (``FS = 2^bit_depth - 1``)::

    I_n(q) = FS * exposure * lit(q) * falloff(X) * rho(X) * p_n(x_p(q))           (+ camera-stage effects)
    rho    = albedo * cos_i + specular * pi * D F G / (4 cos_o)                    (reflectance factor)
    falloff = (d_ref / |X - C_p|)^2                                               (inverse square, 1 at d_ref)

``p_n`` is the projected level (:func:`dptpu.sim.effects.pattern.pattern_levels`), evaluated analytically at
the continuous projector coordinate ``x_p`` (an ideal projector unless pattern-stage effects are on), with the
conventions of :mod:`dptpu.fpp.patterns`: ``p_n = offset + amplitude cos(2 pi f x_p / W + sign 2 pi n / N)``
(the paper's Eq. (1) for ``sign = -1``). ``cos_i``, ``cos_o`` are the cosines between the shading normal and the
directions to the projector and the camera; ``D`` is the GGX distribution with ``alpha = roughness^2``, ``F``
Schlick's Fresnel with ``F0 = ((ior - 1)/(ior + 1))^2``, ``G`` Smith-Schlick shadowing (``k = alpha / 2``); the
specular term is the microfacet BRDF times ``pi cos_i`` so that a Lambertian surface's factor is
``albedo * cos_i``. ``d_ref`` is the projector's distance to the rig's working point. Ambient light is an
effect (``ambient_light``), off by default.

The float frames (:func:`render_frames_float`) carry every effect; :func:`render_frames` quantizes them to
``bit_depth`` (``clip(round(I), 0, FS)``, the ADC).
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.fpp.capture.reading import MAX_STEPS

from .effects import parse_effects
from .effects.camera import apply_camera_effects
from .effects.geometry import has_motion, moved_meshes
from .effects.pattern import defocus_sigma_px, pattern_levels, step_shifts
from .raycast import SurfaceSamples, trace
from .rig import working_point

__all__ = ["SequenceSpec", "parse_sequences", "ShadedSurface", "reflectance_factor", "render_frames",
           "render_frames_float", "quantize", "DEFAULT_OFFSET", "DEFAULT_AMPLITUDE"]

#: Default projected levels (fraction of full scale), as ``dptpu.fpp.patterns.fringe_patterns``.
DEFAULT_OFFSET = 0.5
DEFAULT_AMPLITUDE = 0.45
_KINDS = ("phase", "white", "black")


@dataclass(frozen=True)
class SequenceSpec:
    """One pattern sequence to render.

    Attributes
    ----------
    frequency : float
        Periods across the projector extent along ``axis`` (> 0); ignored for ``white``/``black``.
    steps : int
        ``N >= 3`` for ``phase``; 1 for ``white``/``black``.
    axis : {"x", "y"}
        Fringe axis: ``x`` = phase grows with the projector column (vertical stripes).
    shift_sign : {-1, +1}
        Image n is ``A + B cos(phi + shift_sign 2 pi n / N)``; -1 is the paper's Eq. (1).
    kind : {"phase", "white", "black"}
        Phase-shifted fringes, or a full-on / full-off projector frame.
    phase_offset : float
        Radians added to every step.
    """

    frequency: float = 1.0
    steps: int = 12
    axis: str = "x"
    shift_sign: int = -1
    kind: str = "phase"
    phase_offset: float = 0.0

    def __post_init__(self):
        if self.kind not in _KINDS:
            raise ValueError(f"sequence kind must be one of {', '.join(_KINDS)}; got {self.kind!r}")
        if self.axis not in ("x", "y"):
            raise ValueError(f"sequence axis must be 'x' or 'y'; got {self.axis!r}")
        if self.shift_sign not in (-1, 1):
            raise ValueError(f"sequence shift_sign must be -1 or +1; got {self.shift_sign!r}")
        if self.kind == "phase":
            if isinstance(self.frequency, bool) or not isinstance(self.frequency, numbers.Real) or \
                    not np.isfinite(self.frequency) or self.frequency <= 0:
                raise ValueError(f"sequence frequency must be a number > 0; got {self.frequency!r}")
            if isinstance(self.steps, bool) or not isinstance(self.steps, numbers.Integral) or self.steps < 3:
                raise ValueError(f"sequence steps must be an integer >= 3; got {self.steps!r}")
        else:
            object.__setattr__(self, "steps", 1)
        object.__setattr__(self, "frequency", float(self.frequency))
        object.__setattr__(self, "steps", int(self.steps))

    @property
    def label(self) -> str:
        return self.kind if self.kind != "phase" else f"{self.frequency:g}x{self.steps}"


def parse_sequences(text: str, *, shift_sign: int = -1, projector_size: tuple[int, int] | None = None
                    ) -> list[SequenceSpec]:
    """``"96x12,1x12"`` -> sequences; a token is ``FREQxSTEPS`` with optional ``:y`` (fringe axis), or ``white`` /
    ``black``.

    Refused up front (``ValueError`` naming ``--sequence`` and the range), before anything is rendered: steps
    outside ``[3, MAX_STEPS]`` and, with ``projector_size`` ``(width, height)``, a frequency above half the
    projector's extent along the fringe axis (a period of fewer than 2 projector pixels cannot be projected), as
    a capture file's sequences are (:mod:`dptpu.fpp.capture.reading`).
    """
    sequences = []
    for token in str(text).split(","):
        token = token.strip()
        if token in ("white", "black"):
            sequences.append(SequenceSpec(kind=token, shift_sign=shift_sign))
            continue
        body, _, axis = token.partition(":")
        frequency, sep, steps = body.partition("x")
        try:
            sequences.append(SequenceSpec(float(frequency), int(steps), axis=axis or "x", shift_sign=shift_sign))
        except ValueError as exc:
            reason = exc if sep else "expected FREQxSTEPS"
            raise ValueError(f"--sequence {token!r}: {reason} (e.g. 96x12,1x12 or 64x3:y, white, black)") from None
        spec = sequences[-1]
        if spec.steps > MAX_STEPS:
            raise ValueError(f"--sequence {token!r}: steps must be an integer in [3, {MAX_STEPS}]; got {spec.steps}")
        if projector_size is not None:
            extent = int(projector_size[0 if spec.axis == "x" else 1])
            if spec.frequency > extent / 2:
                raise ValueError(f"--sequence {token!r}: frequency must be in (0, {extent / 2:g}] (a period of at "
                                 f"least 2 projector pixels over its {extent} pixels along {spec.axis}); got "
                                 f"{spec.frequency:g}")
    if not sequences:
        raise ValueError("--sequence must list at least one sequence, e.g. 96x12,1x12")
    return sequences


class ShadedSurface(Protocol):
    """What :func:`reflectance_factor` reads of a surface, per pixel: a :class:`~dptpu.sim.raycast.SurfaceSamples`
    or any object with these arrays (world ``points`` and unit ``normals`` (H, W, 3), ``lit`` (H, W) bool,
    material (H, W))."""

    @property
    def points(self) -> np.ndarray: ...
    @property
    def normals(self) -> np.ndarray: ...
    @property
    def lit(self) -> np.ndarray: ...
    @property
    def albedo(self) -> np.ndarray: ...
    @property
    def roughness(self) -> np.ndarray: ...
    @property
    def specular(self) -> np.ndarray: ...
    @property
    def ior(self) -> np.ndarray: ...


def reflectance_factor(rig: Rig, samples: ShadedSurface) -> np.ndarray:
    """``lit * falloff * rho`` (H, W) float64: the frame of a projector level of 1 at exposure 1 (fraction of FS)."""
    points = samples.points
    normals = samples.normals
    to_projector = rig.projector.center - points
    distance_p = np.linalg.norm(to_projector, axis=-1)
    light = to_projector / distance_p[..., None]
    to_camera = rig.camera.center - points
    view = to_camera / np.linalg.norm(to_camera, axis=-1, keepdims=True)
    cos_i = np.clip(np.einsum("...i,...i->...", normals, light), 0.0, 1.0)
    cos_o = np.clip(np.einsum("...i,...i->...", normals, view), 1e-4, 1.0)
    rho = samples.albedo * cos_i
    specular = samples.specular.astype(np.float64)
    if np.any(specular > 0):
        half = light + view
        half /= np.linalg.norm(half, axis=-1, keepdims=True)
        cos_h = np.clip(np.einsum("...i,...i->...", normals, half), 0.0, 1.0)
        cos_vh = np.clip(np.einsum("...i,...i->...", view, half), 0.0, 1.0)
        alpha = np.maximum(samples.roughness.astype(np.float64) ** 2, 1e-3)
        a2 = alpha * alpha
        D = a2 / (np.pi * (cos_h * cos_h * (a2 - 1.0) + 1.0) ** 2)
        ior = samples.ior.astype(np.float64)
        F0 = ((ior - 1.0) / (ior + 1.0)) ** 2
        F = F0 + (1.0 - F0) * (1.0 - cos_vh) ** 5
        k = alpha / 2.0
        G = (cos_i / (cos_i * (1.0 - k) + k)) * (cos_o / (cos_o * (1.0 - k) + k))
        rho = rho + np.where(cos_i > 0, specular * np.pi * D * F * G / (4.0 * cos_o), 0.0)
    d_ref = float(np.linalg.norm(working_point(rig) - rig.projector.center))
    falloff = (d_ref / distance_p) ** 2
    factor = np.where(samples.lit, falloff * rho, 0.0)
    return np.nan_to_num(factor, nan=0.0)


def _as_sequences(sequences) -> list[SequenceSpec]:
    if isinstance(sequences, SequenceSpec):
        sequences = [sequences]
    out = []
    for i, sequence in enumerate(sequences):
        if not isinstance(sequence, SequenceSpec):
            raise ValueError(f"sequences[{i}] must be a SequenceSpec; got {type(sequence).__name__}")
        out.append(sequence)
    if not out:
        raise ValueError("sequences must hold at least one SequenceSpec")
    return out


def render_frames_float(rig: Rig, samples: SurfaceSamples, sequences, *, effects=None, seed: int = 0,
                        bit_depth: int = 8, exposure: float = 1.0, offset: float = DEFAULT_OFFSET,
                        amplitude: float = DEFAULT_AMPLITUDE) -> list[np.ndarray]:
    """Frames of every sequence as float64 digital numbers, all effects applied, before quantization.

    Parameters
    ----------
    rig : Rig
        The rig whose projector casts the patterns (geometry comes from ``samples``).
    samples : SurfaceSamples
        From :func:`dptpu.sim.raycast.trace`.
    sequences : list of SequenceSpec
    effects : list, optional
        Effect entries or parsed effects; default ``rig.effects``. Only the pattern and camera stages act here
        (and ``motion``, which re-traces ``samples.meshes``); ``lens_distortion`` acts on the trace
        (:func:`dptpu.sim.effects.geometry.render_rig`), ``phase_filter`` in the decoder.
    seed : int
        Seed of every random draw (noise, drift jitter, random step errors): same seed, same frames.
    bit_depth : {8, 16}
        Full scale ``FS = 2^bit_depth - 1``.
    exposure : float
        Scale of the projected term: a white Lambertian surface (albedo 1) facing the projector at the working
        point under level ``p`` records ``p * exposure * FS``.
    offset, amplitude : float
        Projected level ``offset + amplitude cos(.)``, fractions of full scale.

    Returns
    -------
    list of ndarray (N, H, W) float64
    """
    if bit_depth not in (8, 16):
        raise ValueError(f"bit_depth must be 8 or 16; got {bit_depth!r}")
    sequences = _as_sequences(sequences)
    effects = parse_effects(rig.effects if effects is None else effects)
    rng = np.random.default_rng(seed)
    full_scale = float(2 ** bit_depth - 1)
    height, width = samples.shape
    moving = has_motion(effects)

    def geometry(frame_index: int):
        frame_samples = samples
        if moving and frame_index > 0:
            if not samples.meshes:
                raise ValueError("the motion effect needs samples traced from meshes (trace(rig, meshes))")
            frame_samples = trace(samples.rig, moved_meshes(samples.meshes, effects, frame_index))
        factor = reflectance_factor(samples.rig, frame_samples)
        projector_depth = (frame_samples.points @ samples.rig.projector.R.T + samples.rig.projector.T)[..., 2]
        return frame_samples, factor, projector_depth

    static = geometry(0)
    frame_index = 0
    out = []
    for sequence in sequences:
        extent = rig.projector.size[0] if sequence.axis == "x" else rig.projector.size[1]
        shifts = step_shifts(sequence.steps, sequence.shift_sign, effects, rng) if sequence.kind == "phase" else [0.0]
        frames = np.zeros((sequence.steps, height, width))
        for n in range(sequence.steps):
            frame_samples, factor, projector_depth = geometry(frame_index) if moving else static
            frame_index += 1
            if sequence.kind != "phase":
                level = 1.0 if sequence.kind == "white" else 0.0
                frames[n] = full_scale * exposure * factor * level
                continue
            coord = frame_samples.projector_xy[..., 0 if sequence.axis == "x" else 1]
            mask = factor > 0
            levels = pattern_levels(coord[mask], frequency=sequence.frequency, extent=extent, shift=shifts[n],
                                    offset=offset, amplitude=amplitude, phase_offset=sequence.phase_offset,
                                    effects=effects, sigma_px=defocus_sigma_px(effects, projector_depth[mask]))
            frames[n][mask] = full_scale * exposure * factor[mask] * levels
        albedo = samples.albedo.astype(np.float64)
        out.append(apply_camera_effects(frames, effects=effects, albedo=albedo, hit=samples.hit,
                                        full_scale=full_scale, exposure=exposure, rng=rng))
    return out


def quantize(frames: np.ndarray, bit_depth: int = 8) -> np.ndarray:
    """``clip(round(frames), 0, 2^bit_depth - 1)`` as uint8 (8) or uint16 (16)."""
    full_scale = float(2 ** bit_depth - 1)
    dtype = np.uint8 if bit_depth == 8 else np.uint16
    return np.clip(np.rint(frames), 0.0, full_scale).astype(dtype)


def render_frames(rig: Rig, samples: SurfaceSamples, sequences, *, effects=None, seed: int = 0, bit_depth: int = 8,
                  **kwargs) -> list[np.ndarray]:
    """Quantized frames of every sequence, (N, H, W) uint8 (``bit_depth=8``) or uint16 (16).

    Same parameters as :func:`render_frames_float` (``exposure``, ``offset``, ``amplitude`` by keyword).
    """
    return [quantize(frames, bit_depth) for frames in
            render_frames_float(rig, samples, sequences, effects=effects, seed=seed, bit_depth=bit_depth, **kwargs)]
