"""The training samples of one twin scene: noisy few-step inputs, 12-step labels checked against the ray cast.

For one scene (one trace) and every combination of high frequency ``f_h``, method and noise ``sigma``:

1. inputs: ``input_steps`` frames of ``f_h`` and of the method's low frequency ``f_l`` (MF ``f_l = 1``; MW
   ``f_l = f_h - 1``; NT ``f_l = 10.9``: the paper's training set S4), rendered by the raycast twin with the rig's
   effects plus Gaussian camera noise of ``sigma`` gray levels (``sensor_noise`` with ``read_noise_dn = sigma``,
   ``gain_dn_per_electron = 0``; a ``sensor_noise`` of the rig is replaced), quantized to 8 bits. The wrapped phases
   ``psi_h``, ``psi_l`` by least squares (Eq. (2)); ``coarse_order`` = the classical method's fringe order of
   ``f_h`` (MF Eq. (5), MW Eqs. (6)-(7), NT Eqs. (8)-(9)), which may be wrong: that is what the network refines;
2. labels: ``label_steps`` frames of ``f_h`` and ``f_l`` with the rig's effects but no camera noise and no
   quantization; their wrapped phases and the SAME method's formula give the absolute phase
   ``Phi12 = psi12_h + 2 pi k12`` (the paper: labels "computed from dual-frequency, 12-step phase-shifting fringe
   images using the same TPU formulas"). The label is the order that makes the INPUT phase absolute,
   ``label_order = Round((Phi12 - psi_h) / 2 pi)`` (equal to ``k12`` except where input noise moves ``psi_h``
   across a wrap, where ``k12`` would be off by one for the network's input);
3. ``valid``: the camera ray hits a surface the projector lights (the ray cast), the 12-step absolute phase agrees
   with the ray cast's ``2 pi f_h x_p / W`` within ``pi / 2`` (a label whose order is wrong is 2 pi off; these are
   dropped, and counted where the inputs were usable), and the input frames pass
   :func:`dptpu.fpp.phase.quality_mask` (modulation >= 2 % of full scale in both inputs, no saturated frame): the
   pixels the classical pipeline would use too.

Convention: fringes along projector x (vertical stripes), ``W`` = projector width; ``phi = 2 pi f x_p / W``;
wrapped phases in ``[0, 2 pi)``; orders ``k = floor(phi / 2 pi)``.
"""
from __future__ import annotations

import numpy as np

from dptpu.fpp import phase, tpu
from dptpu.fpp.calibration import Rig
from dptpu.fpp.methods import TWO_FREQUENCY_METHODS

from .effects import parse_effects
from .effects.geometry import render_rig
from .image_formation import SequenceSpec, quantize, render_frames_float
from .raycast import trace

__all__ = ["METHODS", "NT_LOW_FREQUENCY", "low_frequency", "check_combination", "scene_samples",
           "MIN_MODULATION_FRACTION", "LABEL_TOLERANCE_RAD"]

METHODS = TWO_FREQUENCY_METHODS  # the methods a dataset may hold samples of
#: The NT auxiliary frequency of the paper's training set.
NT_LOW_FREQUENCY = 10.9
#: Input pixels need a modulation of at least this fraction of full scale (as dptpu.fpp.reconstruct's default).
MIN_MODULATION_FRACTION = 0.02
#: A label is kept where the 12-step absolute phase is within this of the ray cast's (radians).
LABEL_TOLERANCE_RAD = np.pi / 2
_TWO_PI = 2.0 * np.pi
_BIT_DEPTH = 8


def low_frequency(method: str, frequency_high: float) -> float:
    """The paper's auxiliary frequency: MF 1, MW ``f_h - 1``, NT 10.9."""
    if method == "mf":
        return 1.0
    if method == "mw":
        return float(frequency_high) - 1.0
    if method == "nt":
        return NT_LOW_FREQUENCY
    raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")


def check_combination(method: str, frequency_high: float, extent_px: float) -> None:
    """Raise ValueError when ``method`` cannot unwrap ``frequency_high`` with its low frequency."""
    f_l = low_frequency(method, frequency_high)
    if not frequency_high > 1.0:
        raise ValueError(f"--frequencies: {frequency_high:g} must be > 1 (the high frequency of a pair)")
    if method == "nt":
        try:
            tpu.nt_period_pair(frequency_high, f_l, extent_px)
        except ValueError as exc:
            raise ValueError(f"--frequencies {frequency_high:g} with nt (f_l = {f_l:g}): {exc}") from None
    if method == "mw" and not f_l > 0:
        raise ValueError(f"--frequencies {frequency_high:g} with mw needs f_l = f_h - 1 > 0")


def _noise_effects(effects, sigma: float) -> tuple:
    kept = [e for e in effects if e.name != "sensor_noise"]
    if sigma > 0:
        kept.append({"sensor_noise": {"read_noise_dn": float(sigma), "gain_dn_per_electron": 0.0, "dark_dn": 0.0}})
    return parse_effects(kept)


def _render_seed(scene_seed: int, sigma: float, steps: int) -> int:
    """Seed of the frames of one scene at one noise level and step count."""
    key = [int(scene_seed), int(round(sigma * 1e6)), int(steps)]
    return int(np.random.SeedSequence(key).generate_state(1)[0])


def _wrapped(frames: np.ndarray):
    maps = phase.wrapped_phase(frames)  # Eq. (2), shift sign -1 (Eq. (1))
    return maps.phase, maps.modulation


def _float32_wrapped(psi: np.ndarray) -> np.ndarray:
    """``psi`` as float32 still in ``[0, 2 pi)``: values that round up to 2 pi become 0 (the same angle)."""
    out = psi.astype(np.float32)
    out[out >= np.float32(_TWO_PI)] = 0.0
    return out


def scene_samples(rig: Rig, scene, *, scene_seed: int, frequencies, methods, noise_sigmas, input_steps: int = 3,
                  label_steps: int = 12, effects=None) -> list[dict]:
    """Every sample of one scene (module docstring), as dicts of the ``.npz`` keys (docs/dataset.md).

    Parameters
    ----------
    rig : Rig
        The twin's rig at the dataset's camera size.
    scene : Scene or list of SceneMesh
    scene_seed : int
        Recorded in each sample and the root of its noise seeds.
    frequencies : sequence of float
        High frequencies ``f_h`` (periods across the projector width).
    methods : sequence of {"mf", "mw", "nt"}
    noise_sigmas : sequence of float
        Camera noise, gray levels (>= 0).
    input_steps, label_steps : int
        Phase steps of the inputs (>= 3) and of the labels (>= 3).
    effects : list, optional
        Effects of image formation (default ``rig.effects``).

    Returns
    -------
    list of dict
        In the order frequency, method, noise (innermost). Arrays ``(H, W)``: ``wrapped_high``, ``wrapped_low``
        float32 radians in ``[0, 2 pi)``, ``coarse_order`` float32, ``label_order`` int16, ``valid`` bool; scalars
        ``frequency_high``, ``frequency_low``, ``method``, ``noise_sigma``, ``scene_seed``, ``label_rejected``
        (pixels that are lit and pass the input quality mask but were dropped because the 12-step label
        disagreed with the ray cast).
    """
    effects = parse_effects(rig.effects if effects is None else effects)
    meshes = scene.meshes if hasattr(scene, "meshes") else list(scene)
    traced_rig = render_rig(rig, effects)
    samples = trace(traced_rig, meshes)
    extent = float(rig.projector.size[0])
    full_scale = float(2 ** _BIT_DEPTH - 1)
    lit = samples.lit
    x_true = np.where(lit, samples.projector_xy[..., 0], 0.0)  # (H, W) projector column, ray cast

    needed = sorted({float(f) for f in frequencies} | {low_frequency(m, f) for f in frequencies for m in methods})
    label_effects = _noise_effects(effects, 0.0)
    label_frames = render_frames_float(traced_rig, samples, [SequenceSpec(f, label_steps) for f in needed],
                                       effects=label_effects, seed=_render_seed(scene_seed, 0.0, label_steps))
    label_phase = {f: _wrapped(frames)[0] for f, frames in zip(needed, label_frames)}

    inputs = {}  # (f, sigma) -> (psi, usable)
    for sigma in noise_sigmas:
        noisy = _noise_effects(effects, float(sigma))
        rendered = render_frames_float(traced_rig, samples, [SequenceSpec(f, input_steps) for f in needed],
                                       effects=noisy, seed=_render_seed(scene_seed, float(sigma), input_steps))
        for f, float_frames in zip(needed, rendered):
            frames = quantize(float_frames, _BIT_DEPTH)
            psi, modulation = _wrapped(frames)
            psi = _float32_wrapped(psi)
            usable = phase.quality_mask(frames, modulation, min_modulation=MIN_MODULATION_FRACTION * full_scale)
            inputs[(f, float(sigma))] = (psi, usable)

    out = []
    for f_h in frequencies:
        f_h = float(f_h)
        true_phase = _TWO_PI * f_h * x_true / extent
        for method in methods:
            f_l = low_frequency(method, f_h)
            labelled = tpu.unwrap(method, label_phase[f_h], label_phase[f_l], f_h, f_l, extent=extent)
            phi12 = np.where(labelled.valid, labelled.absolute_phase, np.nan)
            with np.errstate(invalid="ignore"):
                agrees = np.abs(phi12 - true_phase) < LABEL_TOLERANCE_RAD  # NaN -> False
            for sigma in noise_sigmas:
                psi_h, usable_h = inputs[(f_h, float(sigma))]
                psi_l, usable_l = inputs[(f_l, float(sigma))]
                coarse = tpu.unwrap(method, psi_h, psi_l, f_h, f_l, extent=extent)
                label = np.rint((np.nan_to_num(phi12) - psi_h) / _TWO_PI)
                valid = lit & agrees & usable_h & usable_l
                out.append({
                    "wrapped_high": psi_h,
                    "wrapped_low": psi_l,
                    "coarse_order": coarse.fringe_order.astype(np.float32),
                    "label_order": np.where(valid, label, 0).astype(np.int16),
                    "valid": valid,
                    "frequency_high": np.float64(f_h),
                    "frequency_low": np.float64(f_l),
                    "method": np.str_(method),
                    "noise_sigma": np.float64(sigma),
                    "scene_seed": np.int64(scene_seed),
                    "label_rejected": np.int64(np.count_nonzero(lit & usable_h & usable_l & ~agrees)),
                })
    return out
