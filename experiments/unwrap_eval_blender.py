"""Test samples rendered by Blender (Cycles), a renderer the network never saw, in the ``dptpu-dataset/1`` layout.

For each random scene: one Blender capture (:func:`dptpu.sim.render.render_capture`, ``engine="blender"``, 16 bit,
no camera noise) of ``input_steps``-step sequences of every high frequency and every low frequency the methods
need. Per noise level ``sigma`` the frames are scaled to 8-bit gray levels, get Gaussian noise of ``sigma`` and
are quantized to 8 bits (as the raycast dataset's inputs); wrapped phases by Eq. (2); the classical order by the
method's formula (Eq. (5), (6)-(7) or (8)-(9)). Labels come from the ray cast's projector column ``x_p``
(``gt.npz``), ``label = Round((2 pi f_h x_p / W - psi_h) / 2 pi)``, the order that makes the input phase absolute;
valid pixels are lit in the ray cast, pass the input quality mask, and the noise-free 16-bit phase of ``f_h``
agrees with ``2 pi f_h x_p / W`` within ``pi / 2`` (Blender's geometry near edges may differ from the ray cast's).
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import yaml

from dptpu.fpp import phase, tpu
from dptpu.fpp.calibration import save_rig
from dptpu.fpp.capture import load_ground_truth, load_sequence_images, read_capture
from dptpu.fpp.dataset import DATASET_FORMAT, sample_name
from dptpu.sim.dataset import scene_seed
from dptpu.sim.dataset_samples import low_frequency
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.render import render_capture
from dptpu.sim.scenes import random_scene

__all__ = ["blender_scene_samples", "write_blender_test_set"]

_FULL_SCALE_8 = 255.0
_FULL_SCALE_16 = 65535.0
_TWO_PI = 2.0 * np.pi
#: As dptpu.sim.dataset_samples: minimum modulation (fraction of full scale) and label agreement (radians).
_MIN_MODULATION_FRACTION = 0.02
_AGREEMENT_RAD = np.pi / 2


def _wrap_pi(angle):
    return np.mod(angle + np.pi, _TWO_PI) - np.pi


def blender_scene_samples(rig, scene, *, scene_seed: int, frequencies, methods, noise_sigmas, input_steps: int,
                          blender_samples: int, work_dir) -> list[dict]:
    """Samples of one scene rendered by Blender (module docstring), in the order frequency, method, noise.

    Parameters
    ----------
    rig : Rig
        At the camera size of the samples; its fringe extent is ``rig.projector.size[0]`` (fringes along x).
    scene : Scene
    scene_seed : int
        Seed of the Cycles sampling and of the added noise.
    frequencies, methods, noise_sigmas : sequences
        High frequencies, ``mf``/``mw``/``nt``, camera noise in gray levels.
    input_steps : int
        Phase steps of the inputs (>= 3).
    blender_samples : int
        Cycles samples per pixel.
    work_dir : path-like
        Folder for the capture (removed afterwards).

    Returns
    -------
    list of dict
        The ``.npz`` keys of a ``dptpu-dataset/1`` sample.
    """
    extent = float(rig.projector.size[0])
    needed = sorted({float(f) for f in frequencies} | {low_frequency(m, f) for f in frequencies for m in methods})
    capture_dir = Path(work_dir)
    render_capture(rig, scene, [SequenceSpec(f, int(input_steps)) for f in needed], capture_dir, engine="blender",
                   effects=[], seed=int(scene_seed) % (2 ** 31), bit_depth=16, blender_samples=int(blender_samples))
    capture = read_capture(capture_dir)
    frames = {capture.frequency_of(s): load_sequence_images(capture, s).astype(np.float64) * (_FULL_SCALE_8 /
              _FULL_SCALE_16) for s in capture.phase_sequences}  # f -> (N, H, W) gray levels, float
    truth = load_ground_truth(capture)
    lit = np.asarray(truth.valid, bool)
    x_p = np.where(lit, np.nan_to_num(np.asarray(truth.projector_x, np.float64)), 0.0)
    shutil.rmtree(capture_dir, ignore_errors=True)

    rng = np.random.default_rng([int(scene_seed) % (2 ** 32), 7])
    inputs = {}
    for sigma in noise_sigmas:
        for f, clean in frames.items():
            noisy = np.clip(np.rint(clean + rng.normal(0.0, float(sigma), clean.shape)), 0, _FULL_SCALE_8)
            maps = phase.wrapped_phase(noisy.astype(np.uint8))
            usable = phase.quality_mask(noisy, maps.modulation,
                                        min_modulation=_MIN_MODULATION_FRACTION * _FULL_SCALE_8)
            psi = maps.phase.astype(np.float32)
            psi[psi >= np.float32(_TWO_PI)] = 0.0
            inputs[(f, float(sigma))] = (psi, usable)
    out = []
    for f_h in frequencies:
        f_h = float(f_h)
        true_phase = _TWO_PI * f_h * x_p / extent
        agrees = np.abs(_wrap_pi(phase.wrapped_phase(frames[f_h]).phase - true_phase)) < _AGREEMENT_RAD
        for method in methods:
            f_l = low_frequency(method, f_h)
            for sigma in noise_sigmas:
                psi_h, usable_h = inputs[(f_h, float(sigma))]
                psi_l, usable_l = inputs[(f_l, float(sigma))]
                coarse = tpu.unwrap(method, psi_h, psi_l, f_h, f_l, extent=extent)
                valid = lit & agrees & usable_h & usable_l
                label = np.rint((true_phase - psi_h) / _TWO_PI)
                out.append({
                    "wrapped_high": psi_h, "wrapped_low": psi_l,
                    "coarse_order": coarse.fringe_order.astype(np.float32),
                    "label_order": np.where(valid, label, 0).astype(np.int16), "valid": valid,
                    "frequency_high": np.float64(f_h), "frequency_low": np.float64(f_l), "method": np.str_(method),
                    "noise_sigma": np.float64(sigma), "scene_seed": np.int64(scene_seed),
                    "label_rejected": np.int64(np.count_nonzero(lit & usable_h & usable_l & ~agrees)),
                })
    return out


def write_blender_test_set(rig, out_dir, *, frequencies, methods, noise, scenes: int, seed: int,
                           input_steps: int = 3, blender_samples: int = 8) -> Path:
    """A ``dptpu-dataset/1`` folder of Blender-rendered random scenes (:func:`blender_scene_samples`).

    Scene ``i`` is :func:`dptpu.sim.scenes.random_scene` of ``scene_seed(seed, i)``, as in
    :func:`dptpu.sim.dataset.write_dataset`. Samples already on disk are not rendered again.

    Raises
    ------
    dptpu.sim.blender.BlenderNotInstalledError
        No Blender environment (``dptpu sim setup-blender``).
    """
    out = Path(out_dir)
    (out / "samples").mkdir(parents=True, exist_ok=True)
    per_scene = len(frequencies) * len(methods) * len(noise)
    document = {"format": DATASET_FORMAT, "renderer": "blender", "rig": "rig.yaml",
                "frequencies": [float(f) for f in frequencies], "methods": list(methods),
                "input_steps": int(input_steps), "labels": "ray cast projector_x", "noise": [float(s) for s in noise],
                "size": list(rig.camera.size), "seed": int(seed), "scenes": int(scenes), "count": scenes * per_scene,
                "per_scene": per_scene, "blender_samples": int(blender_samples), "fringe_axis": "x"}
    save_rig(rig, out / "rig.yaml")
    (out / "dataset.yaml").write_text(yaml.safe_dump(document, sort_keys=False, default_flow_style=None))
    for i in range(int(scenes)):
        names = [out / "samples" / sample_name(0, i * per_scene + j) for j in range(per_scene)]
        if all(p.is_file() for p in names):
            continue
        seed_i = scene_seed(seed, i)
        samples = blender_scene_samples(rig, random_scene(rig, seed_i), scene_seed=seed_i, frequencies=frequencies,
                                        methods=methods, noise_sigmas=noise, input_steps=input_steps,
                                        blender_samples=blender_samples, work_dir=out / f".capture-{i}")
        for path, sample in zip(names, samples):
            np.savez_compressed(path, **sample)
    return out
