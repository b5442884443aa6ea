"""Torch access to a ``dptpu-dataset/1`` folder: random crops, reproducible per (seed, epoch, sample).

Samples are read once (:func:`dptpu.fpp.dataset.read_sample`) and kept in memory. The crop of sample
``i`` in epoch ``e`` is drawn from ``numpy.random.default_rng([seed, e, i])``, and the sample order of an
epoch from ``default_rng([seed, e])``, so a run resumed at epoch ``e`` sees exactly the batches an
uninterrupted run would (no hidden random state to save).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import torch

from dptpu.fpp.dataset import Sample, list_samples, read_sample

from .refine import network_prior

__all__ = ["FringeOrderDataset", "collate", "epoch_order"]


class FringeOrderDataset:
    """Crops of the samples of a dataset folder as tensors.

    Parameters
    ----------
    data_dir : path
        A ``dptpu-dataset/1`` folder.
    crop : (int, int) or None
        Crop height and width in pixels (each <= the smallest sample's); None = whole samples (then all
        samples must have one size to be batched).
    seed : int
        Seed of the crop positions.
    dptpu_priors : bool
        Give the samples to the network with the priors that inference uses for a DP-TPU model
        (:func:`dptpu.models.refine.network_prior`): NT in the MF representation of :mod:`dptpu.models.nt_prior`
        (the band prior's low absolute phase at one period and its MF order), MF and MW with their order read at
        the projector's ends (:mod:`dptpu.models.projector_ends`). False (the U-Net baseline, which sees the
        wrapped phases alone) keeps them as rendered.

    ``dataset.item(i, epoch)`` returns a dict of tensors: ``wrapped_high``, ``wrapped_low``, ``coarse_order``,
    ``label_order`` (float32), ``valid`` (bool), all ``(1, h, w)``, and ``frequency_high`` (float32 scalar).
    """

    def __init__(self, data_dir, *, crop=None, seed: int = 0, dptpu_priors: bool = False):
        self.paths = list_samples(data_dir)
        self.samples: list[Sample] = [read_sample(p) for p in self.paths]
        if dptpu_priors:
            self.samples = [_with_dptpu_prior(s) for s in self.samples]
        self.seed = int(seed)
        shapes = {s.valid.shape for s in self.samples}
        if crop is not None:
            crop = (int(crop[0]), int(crop[1]))
            min_h, min_w = min(h for h, _ in shapes), min(w for _, w in shapes)
            if crop[0] < 1 or crop[1] < 1 or crop[0] > min_h or crop[1] > min_w:
                raise ValueError(f"crop {crop[0]}x{crop[1]} must fit in every sample of {data_dir} "
                                 f"(smallest {min_h}x{min_w})")
        elif len(shapes) > 1:
            raise ValueError(f"{data_dir}: samples have different sizes {sorted(shapes)}; pass a crop")
        self.crop = crop

    def __len__(self) -> int:
        return len(self.samples)

    def item(self, index: int, epoch: int) -> dict:
        sample = self.samples[index]
        height, width = sample.valid.shape
        if self.crop is None:
            rows, cols = slice(0, height), slice(0, width)
        else:
            rng = np.random.default_rng([self.seed, int(epoch), int(index)])
            top = int(rng.integers(0, height - self.crop[0] + 1))
            left = int(rng.integers(0, width - self.crop[1] + 1))
            rows, cols = slice(top, top + self.crop[0]), slice(left, left + self.crop[1])

        def image(array, dtype=torch.float32):
            return torch.from_numpy(np.ascontiguousarray(array[rows, cols])).to(dtype)[None]  # (1, h, w)

        return {
            "wrapped_high": image(sample.wrapped_high),
            "wrapped_low": image(sample.wrapped_low),
            "coarse_order": image(sample.coarse_order),
            "label_order": image(sample.label_order),
            "valid": image(sample.valid, torch.bool),
            "frequency_high": torch.tensor(sample.frequency_high, dtype=torch.float32),
        }


def _with_dptpu_prior(sample: Sample) -> Sample:
    """A sample with the network inputs of :func:`dptpu.models.refine.network_prior`."""
    wrapped_low, coarse = network_prior(sample.method, sample.wrapped_high, sample.wrapped_low, sample.coarse_order,
                                        sample.frequency_high, sample.frequency_low, sample.valid)
    return dataclasses.replace(sample, wrapped_low=np.asarray(wrapped_low, dtype=np.float32),
                               coarse_order=coarse.astype(np.float32))


def epoch_order(n_samples: int, seed: int, epoch: int) -> np.ndarray:
    """The shuffled sample indices of one epoch, ``(n_samples,)`` int."""
    return np.random.default_rng([int(seed), int(epoch)]).permutation(n_samples)


def collate(items: list[dict]) -> dict:
    """Stack item dicts into a batch: images ``(B, 1, h, w)``, ``frequency_high`` ``(B,)``."""
    return {key: torch.stack([item[key] for item in items]) for key in items[0]}
