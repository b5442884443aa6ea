"""Small ``dptpu-dataset/1`` folders from analytic step scenes, made with :mod:`dptpu.fpp` alone.

For tests and for training before (or besides) the digital twin's ``dptpu sim dataset``: no renderer,
no rig; each camera pixel sees a projector column ``x_p`` given by a formula (a tilted, slightly curved
plane with raised and sunken blocks and discs, i.e. fringe-order steps and isolated islands), shadows
where nothing is lit. Per sample:

1. ``phi = 2*pi*f*x_p/W`` for the high and low frequency; ``steps`` phase-shifted images
   ``I_n = A + B cos(phi - 2*pi*n/N)`` (Eq. (1)) with Gaussian noise of ``noise_sigma`` gray levels;
2. wrapped phases by least squares (:func:`dptpu.fpp.phase.wrapped_phase`, Eq. (2));
3. the coarse order by the classical method (:func:`dptpu.fpp.tpu.unwrap`: MF Eq. (5) with
   ``f_l = 1``, MW Eq. (7) with ``f_l = f_h - 1``, NT Eq. (9) with ``f_l = 10.9``);
4. the label: the order that makes the noisy wrapped phase absolute,
   ``k = Round((phi_true - psi_h) / 2pi)`` (equal to ``floor(phi_true / 2pi)`` away from the wraps).

This is NOT the twin: no optics, no projector defocus or gamma, no interreflection.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from dptpu.fpp import phase, tpu
from dptpu.fpp.dataset import DATASET_FORMAT

__all__ = ["LOW_FREQUENCY", "low_frequency", "toy_scene", "toy_sample", "write_toy_dataset"]

#: Low frequency of each method given the high one (the paper's pairs).
LOW_FREQUENCY = {"mf": lambda f_h: 1.0, "mw": lambda f_h: f_h - 1.0, "nt": lambda f_h: 10.9}
_TWO_PI = 2.0 * np.pi


def low_frequency(method: str, frequency_high: float) -> float:
    """The paper's auxiliary frequency for ``method`` (MF 1, MW ``f_h - 1``, NT 10.9)."""
    if method not in LOW_FREQUENCY:
        raise ValueError(f"method must be one of {', '.join(LOW_FREQUENCY)}; got {method!r}")
    return LOW_FREQUENCY[method](float(frequency_high))


def toy_scene(shape, extent_px: float, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Projector column ``x_p`` (H, W) float64, albedo (H, W) in (0, 1] and lit mask (H, W) bool."""
    height, width = shape
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    slope = rng.uniform(0.8, 2.0)  # projector pixels per camera pixel
    x_p = (rng.uniform(0.0, max(extent_px - slope * width, 1.0)) + slope * cols
           + rng.uniform(-0.3, 0.3) * rows + rng.uniform(-1, 1) * 1e-3 * (cols - width / 2) ** 2)
    albedo = rng.uniform(0.4, 1.0) * np.ones(shape)
    lit = np.ones(shape, dtype=bool)
    for _ in range(rng.integers(2, 6)):  # blocks and discs shifted along the fringe axis: order steps
        cy, cx = rng.uniform(0, height), rng.uniform(0, width)
        ry, rx = rng.uniform(4, height / 3), rng.uniform(4, width / 3)
        if rng.random() < 0.5:
            inside = (np.abs(rows - cy) < ry) & (np.abs(cols - cx) < rx)
        else:
            inside = ((rows - cy) / ry) ** 2 + ((cols - cx) / rx) ** 2 < 1.0
        x_p = np.where(inside, x_p + rng.uniform(-150, 150), x_p)
        albedo = np.where(inside, rng.uniform(0.3, 1.0), albedo)
        if rng.random() < 0.4:  # a shadow band beside the step
            band = (np.abs(cols - (cx + rx)) < rng.uniform(1, 4)) & (np.abs(rows - cy) < ry)
            lit &= ~band
    albedo = albedo * (0.85 + 0.15 * np.cos(rows / rng.uniform(8, 30)) * np.cos(cols / rng.uniform(8, 30)))
    lit &= (x_p >= 0) & (x_p < extent_px)
    return x_p, albedo, lit


def _wrapped(x_p, albedo, frequency, extent_px, steps, noise_sigma, rng):
    phi = _TWO_PI * frequency * x_p / extent_px  # (H, W)
    shifts = _TWO_PI * np.arange(steps) / steps  # (N,)
    images = (20.0 + 110.0 * albedo)[None] + (100.0 * albedo)[None] * np.cos(phi[None] - shifts[:, None, None])
    images = np.clip(images + rng.normal(0.0, noise_sigma, images.shape), 0.0, 255.0)
    return phase.wrapped_phase(images).phase, phi


def toy_sample(method: str, frequency_high: float, *, shape=(96, 128), extent_px: float = 912.0, steps: int = 3,
               noise_sigma: float = 1.5693, scene_seed: int = 0) -> dict:
    """One sample as the dict of arrays and scalars a ``dptpu-dataset/1`` ``.npz`` holds."""
    rng = np.random.default_rng(scene_seed)
    x_p, albedo, lit = toy_scene(shape, extent_px, rng)
    f_l = low_frequency(method, frequency_high)
    psi_h, phi_h = _wrapped(x_p, albedo, frequency_high, extent_px, steps, noise_sigma, rng)
    psi_l, _ = _wrapped(x_p, albedo, f_l, extent_px, steps, noise_sigma, rng)
    coarse = tpu.unwrap(method, psi_h, psi_l, frequency_high, f_l, extent=extent_px, valid=lit)
    label = np.rint((phi_h - psi_h) / _TWO_PI)
    return {
        "wrapped_high": np.where(lit, psi_h, 0).astype(np.float32),
        "wrapped_low": np.where(lit, psi_l, 0).astype(np.float32),
        "coarse_order": coarse.fringe_order.astype(np.float32),
        "label_order": np.where(lit, label, 0).astype(np.int16),
        "valid": lit,
        "frequency_high": np.float64(frequency_high),
        "frequency_low": np.float64(f_l),
        "method": np.str_(method),
        "noise_sigma": np.float64(noise_sigma),
        "scene_seed": np.int64(scene_seed),
    }


def write_toy_dataset(out_dir, *, frequencies=(32, 48, 64, 80), methods=("mf", "mw", "nt"), scenes: int = 2,
                      shape=(96, 128), noise_sigmas=(1.5693,), steps: int = 3, seed: int = 0,
                      progress: bool = False) -> Path:
    """Write ``scenes`` samples per (method, frequency, noise) into ``out_dir`` (dataset.yaml + samples/*.npz).

    Scene seeds are ``seed * 100000 + i`` for the running sample index ``i``, so two folders with different
    ``seed`` share no scene. ``progress``: a tqdm bar over the samples on stderr.
    """
    out = Path(out_dir)
    (out / "samples").mkdir(parents=True, exist_ok=True)
    index = 0
    bar = tqdm(total=len(noise_sigmas) * len(methods) * len(frequencies) * scenes, desc="toy samples", unit="sample",
               disable=not progress, file=sys.stderr)
    for noise_sigma in noise_sigmas:
        for method in methods:
            for f_h in frequencies:
                for _ in range(scenes):
                    sample = toy_sample(method, float(f_h), shape=shape, steps=steps, noise_sigma=noise_sigma,
                                        scene_seed=seed * 100000 + index)
                    np.savez_compressed(out / "samples" / f"{index:05d}_{method}_f{f_h:g}_n{noise_sigma:g}.npz",
                                        **sample)
                    index += 1
                    bar.update(1)
    bar.close()
    document = {"format": DATASET_FORMAT, "generator": "dptpu.models.toy_dataset (analytic step scenes, not the twin)",
                "samples": index, "frequencies": [float(f) for f in frequencies], "methods": list(methods),
                "noise_sigmas": [float(n) for n in noise_sigmas], "steps": steps, "shape": list(shape), "seed": seed}
    (out / "dataset.yaml").write_text(yaml.safe_dump(document, sort_keys=False))
    return out
