"""A scan's wrapped phase worked on image by image (fpp/scan_phase.py IncrementalScanPhase, fpp/phase.py
sequence_sums / maps_from_sums) equals the maps of the stacked images (scan_phase_maps)."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp import phase as fpp_phase
from dptpu.fpp.scan_phase import ImageSlot, IncrementalScanPhase, scan_phase_maps

SHAPE = (30, 40)


def fringe_images(frequency, steps, *, dtype, shift_sign=-1, phase_offset=0.0, seed=0):
    """(steps, H, W) images ``A + B cos(phi + phase_offset + shift_sign 2 pi n / N) + noise`` of a ramp phase."""
    rng = np.random.default_rng(seed)
    phi = 2 * np.pi * frequency * np.linspace(0, 1, SHAPE[1])[None, :] + np.zeros(SHAPE)
    scale = 255 if dtype == np.uint8 else 4095
    n = np.arange(steps)[:, None, None]
    images = scale * (0.5 + 0.35 * np.cos(phi + phase_offset + shift_sign * 2 * np.pi * n / steps))
    images = images + rng.normal(0, 0.01 * scale, images.shape)
    images[:, :3, :3] = scale  # a saturated corner
    return np.clip(np.rint(images), 0, scale).astype(dtype), np.mod(phi, 2 * np.pi)


def layout_of(stacks, offsets, shift_sign):
    """The ImageSlot of every image of a scan of ``stacks`` (entries in projection order)."""
    slots, start = [], 0
    for stack, offset in zip(stacks, offsets):
        slots += [ImageSlot(entry_start=start, steps=len(stack), step=step, phase_offset=offset,
                            shift_sign=shift_sign) for step in range(len(stack))]
        start += len(stack)
    return slots


def incremental(stacks, layout, order=None):
    """An IncrementalScanPhase fed the scan's images one at a time (in ``order``, default projection order)."""
    images = [image for stack in stacks for image in stack]
    sums = IncrementalScanPhase()
    for index in order if order is not None else range(len(images)):
        sums.add(index, images[index], layout[index])
    return sums


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_sums_added_image_by_image_give_the_maps_of_the_stacked_images(dtype):
    high, phi_high = fringe_images(16.0, 12, dtype=dtype, seed=1)
    low, _ = fringe_images(1.0, 4, dtype=dtype, seed=2)
    layout = layout_of([high, low], (0.0, 0.0), -1)
    order = np.random.default_rng(0).permutation(len(layout))  # images may arrive in any order
    level = 250.0 if dtype == np.uint8 else None
    ours = incremental([high, low], layout, order).maps(layout, min_modulation=20.0, saturation_level=level)
    stacked = scan_phase_maps([high, low], (0.0, 0.0), shift_sign=-1, min_modulation=20.0, saturation_level=level)
    for mine, theirs in zip(ours[:2], stacked[:2]):
        assert mine.dtype == np.float32 and mine.shape == (2, *SHAPE)
        np.testing.assert_allclose(mine, theirs, atol=2e-5)  # the same sums, up to float32 summation order
    assert np.array_equal(ours[2], stacked[2])
    assert not ours[2][:3, :3].any() and ours[2][5:, 5:].all()  # the saturated corner only
    error = np.angle(np.exp(1j * (ours[0][0] - phi_high)))[5:, 5:]
    assert np.abs(error).max() < 0.08  # the ramp's phase: noise sqrt(2/12) * 1 % / 35 % = 0.012 rad rms


def test_phase_offsets_and_shift_sign_are_applied_image_by_image():
    images, phi = fringe_images(4.0, 5, dtype=np.uint8, shift_sign=1, phase_offset=0.7, seed=3)
    low, _ = fringe_images(1.0, 3, dtype=np.uint8, shift_sign=1, seed=4)
    layout = layout_of([images, low], (0.7, 0.0), 1)
    phases, modulation, _ = incremental([images, low], layout).maps(layout, min_modulation=10.0,
                                                                    saturation_level=None)
    error = np.angle(np.exp(1j * (phases[0] - phi)))[5:, 5:]
    assert np.abs(error).max() < 0.1  # noise sqrt(2/5) * 1 % / 35 % = 0.018 rad rms; a lost offset would be 0.7
    assert 80 < float(np.median(modulation[0])) < 100  # B = 0.35 * 255 = 89 DN


def test_images_added_at_another_place_than_the_layout_give_none():
    images, _ = fringe_images(8.0, 4, dtype=np.uint8)
    low, _ = fringe_images(1.0, 3, dtype=np.uint8)
    layout = layout_of([images, low], (0.0, 0.0), -1)
    sums = incremental([images, low], layout)
    sums.slots[1] = ImageSlot(entry_start=0, steps=4, step=2, phase_offset=0.0, shift_sign=-1)
    assert sums.maps(layout, min_modulation=5.0, saturation_level=None) is None
    assert incremental([images, low], layout, order=range(6)).maps(layout, min_modulation=5.0,
                                                                   saturation_level=None) is None  # one missing


def test_sequence_sums_and_maps_from_sums_are_wrapped_phase():
    images, _ = fringe_images(6.0, 7, dtype=np.uint16, shift_sign=1, phase_offset=-0.4)
    maps = fpp_phase.maps_from_sums(fpp_phase.sequence_sums(images, shift_sign=1, phase_offset=-0.4))
    reference = fpp_phase.wrapped_phase(images, shift_sign=1, phase_offset=-0.4, dtype=np.float32)
    for name in ("phase", "modulation", "background"):  # the same sums; OpenCV's kernels may round 1 ulp apart
        np.testing.assert_allclose(getattr(maps, name), getattr(reference, name), rtol=1e-6, atol=1e-6)
    with pytest.raises(ValueError, match="8- or 16-bit integers"):
        fpp_phase.sequence_sums(images.astype(np.float32))


def test_the_maps_are_the_same_bits_at_any_memory_alignment():
    """The same scan gives the same cloud: OpenCV's cv2.magnitude (the modulation before) rounded about one element
    in 300,000 one ulp apart when the sums started at another address, and a modulation on the threshold made two
    runs of one scan differ by a point."""
    rng = np.random.default_rng(0)
    sums = (rng.normal(size=(3, 480, 640)) * 300).astype(np.float32)
    reference = fpp_phase.maps_from_sums(sums)
    for offset in (4, 8, 12, 16, 20, 28, 36):
        buffer = np.empty(sums.nbytes + 64, dtype=np.uint8)
        moved = buffer[offset:offset + sums.nbytes].view(np.float32).reshape(sums.shape)
        moved[...] = sums
        maps = fpp_phase.maps_from_sums(moved)
        assert np.array_equal(maps.modulation, reference.modulation), offset
        assert np.array_equal(maps.phase, reference.phase), offset
    exact = np.hypot(sums[0].astype(np.float64), sums[1].astype(np.float64))
    assert np.max(np.abs(reference.modulation - exact) / exact) <= 2.0 ** -23  # within an ulp of float32


def test_the_noise_test_of_entries_added_image_by_image_is_the_stacked_reference():
    """The phase node's path (each entry's noise from its own modulation as its last image arrives) and
    scan_phase_maps judge the same pixels noisy."""
    rng = np.random.default_rng(3)
    stacks = []
    for frequency, seed in ((16.0, 5), (1.0, 6)):
        images, _ = fringe_images(frequency, 12, dtype=np.uint8, seed=seed)
        noisy = rng.random(SHAPE) < 0.03  # a few pixels 8x noisier than the rest
        images = images.astype(np.float64) + rng.normal(0, 12.0, size=images.shape) * noisy
        stacks.append(np.clip(np.rint(images), 0, 255).astype(np.uint8))
    layout = layout_of(stacks, (0.0, 0.0), -1)
    ours = incremental(stacks, layout, None).maps(layout, min_modulation=5.0, saturation_level=None)
    _, _, stacked_valid = scan_phase_maps(stacks, (0.0, 0.0), shift_sign=-1, min_modulation=5.0,
                                          saturation_level=None)
    without_noise_test = scan_phase_maps(stacks, (0.0, 0.0), shift_sign=-1, min_modulation=5.0,
                                         saturation_level=None, max_noise_ratio=0)[2]
    assert np.array_equal(ours[2], stacked_valid)
    assert 0 < (without_noise_test & ~stacked_valid).sum()  # the noise test dropped pixels, the same in both
