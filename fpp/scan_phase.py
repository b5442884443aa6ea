"""Wrapped phase of a scan of several N-step sequences, worked on as its images arrive (Eq. (2) of the paper).

A scan is a series of phase-shifted sequences ("entries": one frequency each, ``N_e >= 3`` steps) projected one
after the other; image ``n`` of an entry is ``I_n = A + B cos(psi + phase_offset + shift_sign*2*pi*n/N_e)``.
Where each image sits is an :class:`ImageSlot`.

- :class:`IncrementalScanPhase` takes the images one at a time, as a camera delivers them: each goes into its
  entry's (N, H, W) stack and the brightest value of each pixel is kept; an entry's Eq. (2) sums are computed the
  moment its last image is in (:func:`dptpu.fpp.phase.sequence_sums`, one float32 matrix product), so after the
  scan's last image only its last entry's sums, the arctangents and the masks are left
  (:func:`dptpu.fpp.phase.maps_from_sums`).
- :func:`scan_phase_maps` gives the same maps from the stacked images in one call (the reference, and the
  fallback when the images were placed otherwise than the scan's final layout says).

Both return the wrapped phase ``psi`` (F, H, W) float32 in ``[0, 2*pi)``, the modulation ``B`` (F, H, W) float32
and one validity mask (H, W) for the scan: every entry's modulation at least ``min_modulation``, no image at the
saturation level (:func:`dptpu.fpp.phase.quality_mask`), and in no entry of 5 or more steps a phase noise (measured
from the entry's own fit) of ``max_noise_ratio`` times the scan's median or more (:mod:`dptpu.fpp.fringe_noise`).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .fringe_noise import DEFAULT_MAX_NOISE_RATIO, MIN_NOISE_STEPS, noise_outliers, sequence_phase_noise
from .phase import maps_from_sums, modulation_from_sums, quality_mask, sequence_sums, wrapped_phase

__all__ = ["ImageSlot", "IncrementalScanPhase", "scan_phase_maps"]

_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class ImageSlot:
    """Where an image sits in its scan: the entry starting at image ``entry_start`` (``steps`` images), phase step
    ``step`` in ``[0, steps)``, the entry's ``phase_offset`` (radians) and the scan's ``shift_sign`` (what Eq. (2)
    weighs the image by)."""

    entry_start: int
    steps: int
    step: int
    phase_offset: float
    shift_sign: int


def scan_phase_maps(stacks: Sequence[np.ndarray], phase_offsets: Sequence[float], *, shift_sign: int,
                    min_modulation: float, saturation_level: float | None,
                    max_noise_ratio: float = DEFAULT_MAX_NOISE_RATIO):
    """Wrapped phase, modulation and validity of a scan's stacked entries (Eq. (2) of the paper).

    Parameters
    ----------
    stacks : sequence of ndarray (N_e, H, W)
        One stack per entry, step order ``n = 0..N_e-1``, the camera's digital numbers.
    phase_offsets : sequence of float
        Radians per entry.
    shift_sign : {-1, +1}
        Image ``n`` is ``A + B cos(psi + phase_offset + shift_sign*2*pi*n/N_e)``; -1 is the paper's Eq. (1).
    min_modulation : float
        Smallest modulation ``B`` of a valid pixel, digital numbers.
    saturation_level : float or None
        A pixel with any image ``>=`` this is invalid; None: the integer dtype's maximum.
    max_noise_ratio : float
        A pixel whose phase noise in an entry of 5 or more steps is at least this many times the entry's median is
        invalid (:func:`dptpu.fpp.fringe_noise.noise_outliers`); 0: no such test.

    Returns
    -------
    phases : ndarray (F, H, W) float32
        ``psi`` in ``[0, 2*pi)`` (a float64 phase just below 2*pi that rounds up to it in float32 becomes 0, the
        same angle).
    modulations : ndarray (F, H, W) float32
    valid : ndarray (H, W) bool
        Valid in every entry (:func:`dptpu.fpp.phase.quality_mask`).
    """
    phases, modulations, noise, floors = [], [], [], []
    valid = np.ones(stacks[0].shape[1:], dtype=bool)
    for stack, offset in zip(stacks, phase_offsets):
        maps = wrapped_phase(stack, shift_sign=shift_sign, phase_offset=offset, dtype=np.float32)
        valid &= quality_mask(stack, maps.modulation, min_modulation=min_modulation, saturation_level=saturation_level)
        phase32 = maps.phase.astype(np.float32, copy=False)
        phases.append(np.where(phase32 >= _TWO_PI, np.float32(0.0), phase32))
        modulations.append(maps.modulation.astype(np.float32, copy=False))
        if max_noise_ratio > 0 and stack.shape[0] >= MIN_NOISE_STEPS:  # fewer steps leave no residual
            entry_noise, floor = sequence_phase_noise(stack, maps.background, maps.modulation)
            noise.append(entry_noise)
            floors.append(floor)
    valid &= ~noise_outliers(noise, valid, max_noise_ratio, floors)
    return np.stack(phases), np.stack(modulations), valid


class IncrementalScanPhase:
    """One scan's entries worked on as their images arrive (see the module docstring).

    ``sums[entry_start]`` is the (3, H, W) float32 ``B sin(psi)``, ``B cos(psi)``, ``A`` of the entry starting at
    that image index (Eq. (2)); ``slots`` records where each added image was put, so :meth:`maps` can check them
    against the scan's final layout.
    """

    def __init__(self) -> None:
        self.sums: dict[int, np.ndarray] = {}
        self.modulation: dict[int, np.ndarray] = {}  # entry_start -> B (H, W) float32 of its sums
        self.noise: dict[int, np.ndarray | None] = {}  # entry_start -> phase noise (H, W) of an entry of N >= 5
        self.noise_floor: dict[int, np.ndarray | None] = {}  # entry_start -> its quantization floor (H, W)
        self.slots: dict[int, ImageSlot] = {}  # image index -> where it was added
        self.brightest: np.ndarray | None = None  # (H, W) max over the images, for the saturation mask
        self._stacks: dict[int, np.ndarray] = {}  # entry_start -> (N, H, W) images of an entry not complete yet
        self._filled: dict[int, int] = {}  # entry_start -> images in its stack

    def add(self, index: int, image: np.ndarray, slot: ImageSlot) -> None:
        """Add image ``index`` (H, W) at ``slot``; computes its entry's Eq. (2) sums when it completes the entry.

        An image added twice at one step is the caller's to refuse (the entry would complete early)."""
        start = slot.entry_start
        stack = self._stacks.get(start)
        if stack is None:
            stack = self._stacks[start] = np.empty((slot.steps, *image.shape), dtype=image.dtype)
            self._filled[start] = 0
        stack[slot.step] = image
        self._filled[start] += 1
        if self.brightest is None:
            self.brightest = image.copy()
        else:
            np.maximum(self.brightest, image, out=self.brightest)
        self.slots[int(index)] = slot
        if self._filled[start] == slot.steps:  # every step of the entry
            stack = self._stacks.pop(start)
            sums = self.sums[start] = sequence_sums(stack, shift_sign=slot.shift_sign, phase_offset=slot.phase_offset)
            modulation = self.modulation[start] = modulation_from_sums(sums[0], sums[1])
            if slot.steps >= MIN_NOISE_STEPS:  # the fit's residual: the entry's phase noise (fpp.fringe_noise)
                self.noise[start], self.noise_floor[start] = sequence_phase_noise(stack, sums[2], modulation)

    def maps(self, layout: Sequence[ImageSlot], *, min_modulation: float, saturation_level: float | None,
             max_noise_ratio: float = DEFAULT_MAX_NOISE_RATIO, out=None):
        """Wrapped phase (F, H, W), modulation (F, H, W) and validity (H, W), as :func:`scan_phase_maps` gives
        them from the stacked images; None when the images added are not ``layout`` (image ``i`` at
        ``layout[i]``: the scan's final layout), and the caller then computes the maps from the stacks.

        ``out``: ``(phases, modulations, valid)`` arrays of those shapes and dtypes (float32, float32, bool) to
        compute into (e.g. a publisher's loaned segment), returned as the maps; None: new arrays."""
        if len(self.slots) != len(layout) or self.brightest is None:
            return None
        for index, slot in self.slots.items():
            if not 0 <= index < len(layout) or slot != layout[index]:
                return None
        starts = sorted({slot.entry_start for slot in layout})
        if any(start not in self.sums for start in starts):
            return None
        height, width = self.brightest.shape
        if out is None:
            phases = np.empty((len(starts), height, width), dtype=np.float32)
            modulations = np.empty((len(starts), height, width), dtype=np.float32)
            valid = np.ones((height, width), dtype=bool)
        else:
            phases, modulations, valid = out
            expected = [((len(starts), height, width), np.dtype(np.float32))] * 2 + [((height, width), np.dtype(bool))]
            got = [(array.shape, array.dtype) for array in out]
            if got != expected:
                raise ValueError(f"out must be arrays of (shape, dtype) {expected}; got {got}")
            valid.fill(True)
        for index, start in enumerate(starts):
            maps = maps_from_sums(self.sums[start], self.modulation[start])
            phases[index] = maps.phase  # in [0, 2*pi) in float32
            modulations[index] = maps.modulation
            valid &= maps.modulation >= min_modulation  # NaN compares False
        if saturation_level is None and np.issubdtype(self.brightest.dtype, np.integer):
            saturation_level = np.iinfo(self.brightest.dtype).max
        if saturation_level is not None:
            valid &= self.brightest < saturation_level  # no image at the saturation level
        if max_noise_ratio > 0:
            valid &= ~noise_outliers([self.noise.get(start) for start in starts], valid, max_noise_ratio,
                                     [self.noise_floor.get(start) for start in starts])
        return phases, modulations, valid

    def background(self, out: np.ndarray | None = None) -> np.ndarray | None:
        """Mean intensity ``A`` (H, W) float32 of the scan's complete entries (Eq. (2): ``A = mean_n I_n``),
        averaged over the entries (into ``out``, an (H, W) float32 array, when given); None before an entry is
        complete."""
        if not self.sums:
            return None
        starts = sorted(self.sums)
        total = self.sums[starts[0]][2].copy() if out is None else out  # (H, W) float32
        if out is not None:
            np.copyto(out, self.sums[starts[0]][2])
        for start in starts[1:]:
            total += self.sums[start][2]
        total /= np.float32(len(starts))
        return total
