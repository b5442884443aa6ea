"""Training samples of the twin built like a measured pair: the same sequences, the same pair construction.

The downstream gain (:mod:`dptpu.experiments.downstream`) fine-tunes the network on twin renders and scores it on
measured pairs (:mod:`.cfpe_inputs`, :mod:`.sphere_inputs`). Those pairs are not the paper's plain MF set (``dptpu sim
dataset``): CFPE's low phase is a heterodyne of three close periods, the sphere's high phase is a 12-step phase.
A :class:`PairDesign` names the sequences and the construction, and :func:`twin_pair_sample` renders a random
scene through the twin (the rig's effects, Gaussian camera noise, 8 bits) and builds the pair from the rendered
frames with the SAME functions as the measured one; the label is the order of the noise-free 12-step phase,
unwrapped the same way and checked against the ray cast (within ``pi / 2``), as :mod:`dptpu.sim.dataset_samples`
does. Samples are written in the ``dptpu-dataset/1`` format (read by :mod:`dptpu.fpp.dataset`) so
``dptpu train`` reads them.

Every input sequence is rendered as 12 frames and its ``N``-step input is every ``12/N``-th frame (steps 0, 4, 8
for ``N = 3``: a 3-step sequence of Eq. (1)), as the CFPE inputs are taken from the real 12-step frames.
"""
from __future__ import annotations

import os
import sys
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from dptpu.fpp import phase, tpu
from dptpu.fpp.calibration import Rig, save_rig
from dptpu.sim.dataset import scene_seed as dataset_scene_seed
from dptpu.sim.effects import Effect, parse_effects
from dptpu.sim.effects.geometry import render_rig
from dptpu.sim.image_formation import SequenceSpec, quantize, render_frames_float
from dptpu.sim.raycast import trace
from dptpu.sim.rig import resize_camera
from dptpu.sim.scenes import random_scene

from .beat_cascade import CascadePair, cascade_pair
from .cfpe_inputs import FREQUENCIES as CFPE_FREQUENCIES
from .cfpe_inputs import build_pair
from .measured_pair import mf_coarse_order, reference_order

__all__ = ["PairDesign", "CFPE_DESIGN", "CFPE_CASCADE_DESIGN", "CASCADE", "SPHERE_DESIGN", "twin_pair_sample",
           "twin_cascade", "twin_cascade_samples", "twin_cascades", "write_twin_set", "RENDER_STEPS"]

#: Frames rendered per sequence; inputs of N steps are every (12/N)-th frame.
RENDER_STEPS = 12
LABEL_TOLERANCE_RAD = np.pi / 2
_TWO_PI = 2.0 * np.pi
_BIT_DEPTH = 8
_MIN_MODULATION_FRACTION = 0.02
#: ``PairDesign.low`` of the three-frequency heterodyne read as a cascade of two MF pairs (:mod:`.beat_cascade`).
CASCADE = "cascade"


@dataclass(frozen=True)
class PairDesign:
    """Sequences and pair construction of a measured data set.

    Attributes
    ----------
    name : str
        ``cfpe`` or ``sphere``.
    frequencies : tuple of float
        Periods across the projector width, highest first.
    input_steps : tuple of int
        Steps of each frequency's input (a divisor of 12).
    shift_sign : int
        Sign of the phase step (CFPE projects ``+2 pi n / N``).
    offset, amplitude : float
        Projected level ``offset + amplitude cos(.)``, fractions of full scale.
    low : str
        ``het12`` / ``beat123`` (three frequencies, :func:`.cfpe_inputs.low_phase`), ``cascade`` (three
        frequencies, both levels of :mod:`.beat_cascade`: a sample of each level per render) or ``mf`` (the second
        frequency is ``f_l = 1``).
    max_correction : int or None
        Training pixels are kept only where the classical order is within this many orders of the label (None: all).
        The network sees an order error through its consistency channel, clipped at 4 orders (docs/network.md);
        the heterodyne's second-level failures move whole regions by ``f_h / f_12 = 15`` orders, and with them
        in the squared loss a short fine-tune learns to blur every order (measured: accuracy 0.73 -> 0.16 on
        CFPE). Only the training labels are masked; the evaluation scores every valid pixel.
    """

    name: str
    frequencies: tuple
    input_steps: tuple
    shift_sign: int = -1
    offset: float = 0.5
    amplitude: float = 0.45
    low: str = "mf"
    max_correction: int | None = None

    def as_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


CFPE_DESIGN = PairDesign("cfpe", tuple(CFPE_FREQUENCIES), (3, 3, 3), shift_sign=1, offset=128 / 255,
                         amplitude=96 / 255, low="het12", max_correction=4)
SPHERE_DESIGN = PairDesign("sphere", (96.0, 1.0), (12, 3), low="mf")
#: CFPE's heterodyne as the cascade of :mod:`.beat_cascade`: one pair per level, a sample of each per render.
CFPE_CASCADE_DESIGN = replace(CFPE_DESIGN, low=CASCADE)


def _effects(effects, sigma: float):
    """The rig's effects with ``sensor_noise`` replaced by Gaussian noise of ``sigma`` DN (none at 0)."""
    kept: list[Effect | dict[str, dict[str, float]]] = [e for e in parse_effects(effects) if e.name != "sensor_noise"]
    if sigma > 0:
        kept.append({"sensor_noise": {"read_noise_dn": float(sigma), "gain_dn_per_electron": 0.0, "dark_dn": 0.0}})
    return parse_effects(kept)


def _phases(frames_list, steps, shift_sign: int) -> tuple[list, np.ndarray]:
    """Wrapped phases of every-(12/N)-th frame of each sequence, and their joint quality mask."""
    phases, mask = [], None
    for frames, n in zip(frames_list, steps):
        if RENDER_STEPS % int(n):
            raise ValueError(f"input steps must divide {RENDER_STEPS}; got {n}")
        subset = frames[::RENDER_STEPS // int(n)]
        maps = phase.wrapped_phase(subset, shift_sign=shift_sign)
        ok = phase.quality_mask(subset, maps.modulation,
                                min_modulation=_MIN_MODULATION_FRACTION * (2 ** _BIT_DEPTH - 1))
        phases.append(maps.phase)
        mask = ok if mask is None else mask & ok
    if mask is None:
        raise ValueError("no phase sequence to wrap")
    return phases, mask


def _reference(design: PairDesign, psi12) -> tpu.Unwrapped:
    if design.low == "mf":
        return tpu.unwrap_mf(psi12[0], psi12[1], design.frequencies[0], design.frequencies[1])
    return tpu.unwrap_heterodyne(psi12, list(design.frequencies))


def _render_inputs(rig: Rig, scene, design: PairDesign, *, noise_sigma: float, seed: int) -> dict:
    """The rendered inputs of one scene: ``psi`` (wrapped input phases, highest first), ``usable`` (their quality
    mask), ``reference`` (the noise-free 12-step absolute phase of ``f_h`` where it agrees with the ray cast, NaN
    elsewhere), ``extent`` (projector width, px) and ``label_rejected`` (lit usable pixels without a label)."""
    meshes = scene.meshes if hasattr(scene, "meshes") else list(scene)
    effects = rig.effects
    traced_rig = render_rig(rig, _effects(effects, 0.0))
    samples = trace(traced_rig, meshes)
    extent = float(rig.projector.size[0])
    specs = [SequenceSpec(float(f), RENDER_STEPS, shift_sign=design.shift_sign) for f in design.frequencies]
    label_frames = render_frames_float(traced_rig, samples, specs, effects=_effects(effects, 0.0), seed=seed,
                                       offset=design.offset, amplitude=design.amplitude)
    psi_label = [phase.wrapped_phase(f, shift_sign=design.shift_sign).phase for f in label_frames]
    labelled = _reference(design, psi_label)
    f_h = float(design.frequencies[0])
    true_phase = _TWO_PI * f_h * np.where(samples.lit, samples.projector_xy[..., 0], 0.0) / extent
    phi12 = np.where(labelled.valid, labelled.absolute_phase, np.nan)
    with np.errstate(invalid="ignore"):
        agrees = samples.lit & (np.abs(phi12 - true_phase) < LABEL_TOLERANCE_RAD)
    noisy = render_frames_float(traced_rig, samples, specs, effects=_effects(effects, noise_sigma), seed=seed + 1,
                                offset=design.offset, amplitude=design.amplitude)
    psi, usable = _phases([quantize(f, _BIT_DEPTH) for f in noisy], design.input_steps, design.shift_sign)
    return {"psi": psi, "usable": usable, "reference": np.where(agrees, phi12, np.nan), "extent": extent,
            "label_rejected": int(np.count_nonzero(samples.lit & usable & ~agrees))}


def _sample(design: PairDesign, psi_h, psi_l, coarse, label, valid, f_h: float, *, noise_sigma: float,
            scene_seed: int, label_rejected: int) -> dict:
    """The ``dptpu-dataset/1`` keys of one pair; labels kept within ``design.max_correction`` of ``coarse``."""
    if design.max_correction is not None:
        valid = valid & (np.abs(coarse.astype(np.int64) - label) <= int(design.max_correction))
    psi_h32 = psi_h.astype(np.float32)
    psi_h32[psi_h32 >= np.float32(_TWO_PI)] = 0.0
    psi_l32 = psi_l.astype(np.float32)
    psi_l32[psi_l32 >= np.float32(_TWO_PI)] = 0.0
    return {"wrapped_high": psi_h32, "wrapped_low": psi_l32, "coarse_order": coarse.astype(np.float32),
            "label_order": np.where(valid, label, 0).astype(np.int16), "valid": valid,
            "frequency_high": np.float64(f_h), "frequency_low": np.float64(1.0), "method": np.str_("mf"),
            "noise_sigma": np.float64(noise_sigma), "scene_seed": np.int64(scene_seed),
            "label_rejected": np.int64(label_rejected)}


def twin_pair_sample(rig: Rig, scene, design: PairDesign, *, noise_sigma: float, seed: int, scene_seed: int = 0,
                     effects=None) -> dict:
    """One training sample (the ``dptpu-dataset/1`` keys) of ``scene`` built like the measured pair.

    Parameters
    ----------
    rig : Rig
        The twin's rig at the sample's camera size; its ``effects`` act unless ``effects`` is given.
    scene : Scene or list of SceneMesh
    design : PairDesign
        Not ``cascade`` (:func:`twin_cascade_samples`).
    noise_sigma : float
        Camera noise of the inputs, DN (the rig's ``sensor_noise`` is replaced).
    seed : int
        Seed of the noise.
    """
    if design.low == CASCADE:
        raise ValueError("a cascade design gives one sample per level: twin_cascade_samples")
    rig = rig if effects is None else replace(rig, effects=tuple(effects))
    inputs = _render_inputs(rig, scene, design, noise_sigma=noise_sigma, seed=seed)
    psi, usable, reference, extent = inputs["psi"], inputs["usable"], inputs["reference"], inputs["extent"]
    f_h = float(design.frequencies[0])
    if design.low == "mf":
        valid = usable & np.isfinite(reference)
        psi_h, psi_l = np.where(valid, psi[0], 0.0), np.where(valid, psi[1], 0.0)
        coarse = mf_coarse_order(psi_h, psi_l, f_h, valid)
        label = reference_order(np.where(valid, reference, np.nan), psi_h)
    else:
        pair = build_pair("twin", psi, usable, reference, design.frequencies, extent_px=int(extent), low=design.low)
        valid, psi_h, psi_l, coarse, label = (pair.valid, pair.wrapped_high, pair.wrapped_low, pair.coarse_order,
                                              pair.reference_order)
    return _sample(design, psi_h, psi_l, coarse, label, valid, f_h, noise_sigma=noise_sigma, scene_seed=scene_seed,
                   label_rejected=inputs["label_rejected"])


def twin_cascade(rig: Rig, scene, design: PairDesign, *, noise_sigma: float, seed: int) -> CascadePair:
    """The cascade's two pairs (:mod:`.beat_cascade`) of a twin scene, built like the measured ones
    (:func:`.cfpe_inputs.cfpe_cascade`: the same :func:`.beat_cascade.cascade_pair`); the reference is the
    noise-free 12-step phase that agrees with the ray cast."""
    inputs = _render_inputs(rig, scene, design, noise_sigma=noise_sigma, seed=seed)
    return cascade_pair("twin", inputs["psi"], inputs["usable"], inputs["reference"], design.frequencies,
                        extent_px=int(inputs["extent"]))


def twin_cascade_samples(rig: Rig, scene, design: PairDesign, *, noise_sigma: float, seed: int,
                         scene_seed: int = 0) -> list[dict]:
    """Two training samples of a twin scene, one per level of the cascade: level 1 (the beat pair, its classical
    order as the prior) and level 2 (the top pair with the low phase of the RIGHT level-1 order: what level 2 sees
    when level 1 is solved). Labels within ``design.max_correction`` of each level's classical order."""
    cascade = twin_cascade(rig, scene, design, noise_sigma=noise_sigma, seed=seed)
    top = cascade.top_pair(cascade.beat.reference_order)
    return [_sample(design, p.wrapped_high, p.wrapped_low, p.coarse_order, p.reference_order, p.valid,
                    p.frequency_high, noise_sigma=noise_sigma, scene_seed=scene_seed, label_rejected=0)
            for p in (cascade.beat, top)]


def twin_cascades(rig: Rig, design: PairDesign, *, scenes: int, size=(320, 240), noise=(1.5693, 3.1386),
                  seed: int = 0, name: str = "twin", progress: bool = False) -> list[CascadePair]:
    """The cascades of ``scenes`` random scenes x ``noise`` levels (held-out scenes: the seeds of
    :func:`write_twin_set`), named ``NAME/SCENE_SEED-NOISE`` (``progress``: a tqdm bar over the scenes on stderr)."""
    size = tuple(int(v) for v in size)
    rig = resize_camera(rig, size) if tuple(rig.camera.size) != size else rig
    cascades = []
    for i in tqdm(range(int(scenes)), desc=name, unit="scene", disable=not progress, file=sys.stderr):
        seed_i = dataset_scene_seed(seed, i)
        scene = random_scene(rig, seed_i)
        for j, sigma in enumerate(noise):
            cascade = twin_cascade(rig, scene, design, noise_sigma=float(sigma), seed=seed_i + j)
            label = f"{name}/{seed_i}-{float(sigma):g}"
            cascades.append(replace(cascade, top=replace(cascade.top, name=label, provenance={
                "data": f"twin, noise {float(sigma):g} DN"}), beat=replace(cascade.beat, name=f"{label}/beat")))
    return cascades


def write_twin_set(rig: Rig, design: PairDesign, out_dir, *, scenes: int, size=(320, 240),
                   noise=(1.5693, 3.1386), seed: int = 0, progress: bool = False) -> Path:
    """Render ``scenes`` random scenes x ``noise`` levels as a ``dptpu-dataset/1`` folder; returns it
    (``progress``: a tqdm bar over the scenes on stderr).

    Scene ``i`` has the seed of ``dptpu sim dataset`` (:func:`dptpu.sim.dataset.scene_seed`): two rigs that
    differ only in their effects render the same scenes, so two sets differ only by the effects.
    """
    if int(scenes) < 1:
        raise ValueError(f"--scenes must be >= 1; got {scenes}")
    noise = tuple(float(s) for s in noise)
    if not noise or any(not np.isfinite(s) or s < 0 for s in noise):
        raise ValueError(f"--noise must list sigmas >= 0 (DN); got {list(noise)}")
    size = tuple(int(v) for v in size)
    rig = resize_camera(rig, size) if tuple(rig.camera.size) != size else rig
    out = Path(out_dir)
    (out / "samples").mkdir(parents=True, exist_ok=True)
    save_rig(rig, out / "rig.yaml")
    index = 0
    frequencies = {float(design.frequencies[0])}
    for i in tqdm(range(int(scenes)), desc=out.name, unit="scene", disable=not progress, file=sys.stderr):
        seed_i = dataset_scene_seed(seed, i)
        scene = random_scene(rig, seed_i)
        for j, sigma in enumerate(noise):
            if design.low == CASCADE:
                samples = twin_cascade_samples(rig, scene, design, noise_sigma=sigma, seed=seed_i + j,
                                               scene_seed=seed_i)
            else:
                samples = [twin_pair_sample(rig, scene, design, noise_sigma=sigma, seed=seed_i + j, scene_seed=seed_i)]
            for sample in samples:
                path = out / "samples" / f"0-{index:06d}.npz"
                tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
                with open(tmp, "wb") as handle:
                    np.savez_compressed(handle, **sample)
                os.replace(tmp, path)
                frequencies.add(float(sample["frequency_high"]))
                index += 1
    document = {"format": "dptpu-dataset/1", "rig": "rig.yaml", "design": design.as_dict(), "scenes": int(scenes),
                "noise": list(noise), "size": list(size), "seed": int(seed), "count": index,
                "methods": ["mf"], "frequencies": sorted(frequencies),
                "made_by": "dptpu.sim.diagnosis.twin_pairs.write_twin_set"}
    (out / "dataset.yaml").write_text(yaml.safe_dump(document, sort_keys=False, default_flow_style=None))
    return out
