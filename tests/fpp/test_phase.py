"""Tests for dptpu.fpp.phase: least-squares wrapped phase (Eq. (2) of the paper)."""

import numpy as np
import pytest

from dptpu.fpp._lsq_phase import angle_0_2pi_float32
from dptpu.fpp.patterns import fringe_patterns, projector_phase
from dptpu.fpp.phase import WrappedPhase, check_bit_depth, quality_mask, wrapped_phase


def wrapped_difference(a, b):
    """a - b wrapped into (-pi, pi]."""
    return np.angle(np.exp(1j * (a - b)))


def synthetic_stack(phase, background, modulation, steps, shift_sign=-1, phase_offset=0.0):
    n = np.arange(steps)[:, None, None]
    return background + modulation * np.cos(
        phase[None] + phase_offset + shift_sign * 2 * np.pi * n / steps
    )


def smooth_scene(height=64, width=96):
    v, u = np.mgrid[0:height, 0:width]
    phase = 0.37 * u + 0.05 * v + 0.3 * np.sin(u / 7.0)  # many wraps
    background = 100 + 20 * np.cos(v / 9.0)
    modulation = 60 + 10 * np.sin(u / 11.0)
    return phase, background, modulation


@pytest.mark.parametrize("steps", [3, 4, 12])
@pytest.mark.parametrize("shift_sign", [-1, 1])
def test_exact_recovery_on_noiseless_images(steps, shift_sign):
    phase, background, modulation = smooth_scene()
    images = synthetic_stack(phase, background, modulation, steps, shift_sign, phase_offset=0.7)
    maps = wrapped_phase(images, shift_sign=shift_sign, phase_offset=0.7)
    assert isinstance(maps, WrappedPhase)
    assert maps.phase.shape == maps.modulation.shape == maps.background.shape == (64, 96)
    assert maps.phase.dtype == np.float64
    assert maps.phase.min() >= 0.0 and maps.phase.max() < 2 * np.pi
    assert np.abs(wrapped_difference(maps.phase, phase)).max() < 1e-9
    np.testing.assert_allclose(maps.modulation, modulation, rtol=0, atol=1e-9)
    np.testing.assert_allclose(maps.background, background, rtol=0, atol=1e-9)


def test_wrong_shift_sign_mirrors_the_phase():
    phase, background, modulation = smooth_scene()
    images = synthetic_stack(phase, background, modulation, 4, shift_sign=-1)
    maps = wrapped_phase(images, shift_sign=1)
    assert np.abs(wrapped_difference(maps.phase, -phase)).max() < 1e-9


def test_wrapped_phase_is_in_zero_to_two_pi_at_the_wrap():
    phase = np.array([[0.0, -1e-17, 2 * np.pi - 1e-13, np.pi]])
    images = synthetic_stack(phase, 10.0, 5.0, 4)
    psi = wrapped_phase(images).phase
    assert psi.min() >= 0.0 and psi.max() < 2 * np.pi
    assert psi[0, 3] == pytest.approx(np.pi, abs=1e-12)


@pytest.mark.parametrize("steps", [4, 12])
def test_phase_noise_matches_theory(steps):
    rng = np.random.default_rng(0)
    height = width = 200
    v, u = np.mgrid[0:height, 0:width]
    phase = 0.21 * u + 0.13 * v
    background, modulation, sigma = 120.0, 50.0, 1.0
    images = synthetic_stack(phase, background, modulation, steps)
    images = images + rng.normal(0.0, sigma, images.shape)
    maps = wrapped_phase(images)
    measured = np.std(wrapped_difference(maps.phase, phase))
    expected = np.sqrt(2.0 / steps) * sigma / modulation
    assert measured == pytest.approx(expected, rel=0.05)
    assert np.mean(maps.modulation) == pytest.approx(modulation, rel=0.01)
    assert np.mean(maps.background) == pytest.approx(background, abs=0.05)


@pytest.mark.parametrize("bit_depth", [8, 16])
def test_integer_input_within_quantization_bound(bit_depth):
    # The projector patterns seen directly: phase = projector phase. Rounding errors |e_n| <= 1/2
    # move S + iC = (N/2) B exp(i psi) by |sum_n e_n exp(i delta_n)| <= N/2, so the phase error is
    # at most asin(1 / B).
    size, frequency, steps = (160, 8), 7.3, 4
    images = fringe_patterns(
        frequency=frequency, steps=steps, projector_size=size, bit_depth=bit_depth
    )
    full_scale = 2**bit_depth - 1
    maps = wrapped_phase(images, bit_depth=bit_depth)
    truth = projector_phase(size, frequency)
    bound = np.arcsin(1.0 / (0.45 * full_scale))
    error = np.abs(wrapped_difference(maps.phase, truth))
    assert error.max() <= bound
    assert error.max() > 0.0  # quantization is really there
    np.testing.assert_allclose(maps.modulation, 0.45 * full_scale, rtol=0.02)
    np.testing.assert_allclose(maps.background, 0.5 * full_scale, atol=0.5)
    # Same numbers as float input of the same values (computed in float64), to float32 precision.
    as_float = wrapped_phase(images.astype(np.float64))
    assert np.abs(wrapped_difference(maps.phase, as_float.phase)).max() < 1e-6
    np.testing.assert_allclose(maps.modulation, as_float.modulation, rtol=1e-6)


def test_quality_mask_flags_low_modulation_and_saturation():
    phase, background, modulation = smooth_scene(8, 10)
    modulation = np.full((8, 10), 60.0)
    modulation[2, 3] = 4.0  # dark / low-contrast pixel
    images = synthetic_stack(phase, background, modulation, 4)
    images = np.clip(np.rint(images), 0, 255).astype(np.uint8)
    images[1, 5, 6] = 255  # saturated in one frame
    maps = wrapped_phase(images)
    mask = quality_mask(images, maps.modulation, min_modulation=10.0)
    expected = np.ones((8, 10), bool)
    expected[2, 3] = False
    expected[5, 6] = False
    np.testing.assert_array_equal(mask, expected)
    # Float input: no saturation check unless a level is given.
    float_images = images.astype(np.float64)
    assert quality_mask(float_images, maps.modulation, min_modulation=10.0)[5, 6]
    assert not quality_mask(
        float_images, maps.modulation, min_modulation=10.0, saturation_level=250.0
    )[5, 6]


def test_quality_mask_bad_shapes():
    images = np.zeros((4, 8, 10))
    with pytest.raises(ValueError, match=r"modulation must have shape \(H, W\) = \(8, 10\)"):
        quality_mask(images, np.zeros((8, 9)), min_modulation=1.0)
    with pytest.raises(ValueError, match="min_modulation must be a finite number >= 0"):
        quality_mask(images, np.zeros((8, 10)), min_modulation=-1.0)


def test_bad_input_raises_naming_the_problem():
    with pytest.raises(ValueError, match=r"shape \(N, H, W\) with N >= 3; got \(2, 48, 64\)"):
        wrapped_phase(np.zeros((2, 48, 64)))
    with pytest.raises(ValueError, match=r"shape \(N, H, W\) with N >= 3; got \(48, 64\)"):
        wrapped_phase(np.zeros((48, 64)))
    nan_images = np.ones((4, 8, 8))
    nan_images[2, 3, 3] = np.nan
    with pytest.raises(ValueError, match="images contain NaN"):
        wrapped_phase(nan_images)
    inf_images = np.ones((4, 8, 8))
    inf_images[0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="images contain inf"):
        wrapped_phase(inf_images)
    with pytest.raises(ValueError, match="integer or float dtype; got bool"):
        wrapped_phase(np.zeros((4, 8, 8), bool))
    with pytest.raises(ValueError, match="shift_sign must be -1 or"):
        wrapped_phase(np.zeros((4, 8, 8)), shift_sign=2)


def test_sixteen_bit_image_declared_eight_bit():
    twelve_bit = np.full((4, 8, 8), 100, np.uint16)
    twelve_bit[1, 2, 2] = 4095
    with pytest.raises(ValueError, match="image values reach 4095 but bit_depth is 8"):
        wrapped_phase(twelve_bit, bit_depth=8)
    with pytest.raises(ValueError, match="image values reach 4095 but bit_depth is 8"):
        check_bit_depth(twelve_bit, 8)
    check_bit_depth(twelve_bit, 12)  # fits
    check_bit_depth(twelve_bit, 16)
    check_bit_depth(np.full((4, 8, 8), 200, np.uint16), 8)  # 8-bit values in a uint16 container


def test_check_bit_depth_dtype_and_range():
    with pytest.raises(ValueError, match="dtype uint8 cannot hold 16-bit values"):
        check_bit_depth(np.zeros((3, 4, 4), np.uint8), 16)
    with pytest.raises(ValueError, match="image values reach 300.0 but bit_depth is 8"):
        check_bit_depth(np.full((3, 4, 4), 300.0), 8)
    with pytest.raises(ValueError, match="image values reach -1 but must be >= 0"):
        check_bit_depth(np.full((3, 4, 4), -1, np.int16), 8)
    with pytest.raises(ValueError, match="bit_depth must be an integer in 1..16; got 32"):
        check_bit_depth(np.zeros((3, 4, 4), np.uint8), 32)


def reference_maps(images, shift_sign=-1, phase_offset=0.0):
    """Eq. (2) written out in float64, frame by frame: (phase in [0, 2pi), modulation, background)."""
    steps = images.shape[0]
    delta = phase_offset + shift_sign * 2 * np.pi * np.arange(steps) / steps
    frames = images.astype(np.float64)
    s = -sum(np.sin(d) * frame for d, frame in zip(delta, frames))
    c = sum(np.cos(d) * frame for d, frame in zip(delta, frames))
    return np.mod(np.arctan2(s, c), 2 * np.pi), 2.0 / steps * np.hypot(s, c), frames.mean(axis=0)


@pytest.mark.parametrize("dtype, full_scale", [(np.uint8, 255), (np.uint16, 65535)])
@pytest.mark.parametrize("steps, shift_sign, offset", [(12, -1, 0.0), (3, 1, 0.4), (5, -1, -2.0)])
def test_fast_integer_path_equals_the_float64_formula(dtype, full_scale, steps, shift_sign, offset):
    # 8/16-bit stacks go through float32 sums and a float32 arctangent: within 1e-6 rad of Eq. (2) in
    # float64 where B is a fifth of full scale or more (5e-7 rad measured), modulation within 1e-6 relative.
    rng = np.random.default_rng(0)
    phase, _, _ = smooth_scene(120, 160)
    background = full_scale * (0.45 + 0.05 * rng.random((120, 160)))
    modulation = full_scale * (0.2 + 0.2 * rng.random((120, 160)))
    images = synthetic_stack(phase, background, modulation, steps, shift_sign, offset)
    images = np.clip(np.rint(images + rng.normal(0, 0.5, images.shape)), 0, full_scale).astype(dtype)
    maps = wrapped_phase(images, shift_sign=shift_sign, phase_offset=offset)
    psi, b, a = reference_maps(images, shift_sign, offset)
    assert maps.phase.dtype == np.float64
    assert maps.phase.min() >= 0.0 and maps.phase.max() < 2 * np.pi
    assert np.abs(wrapped_difference(maps.phase, psi)).max() < 1e-6
    np.testing.assert_allclose(maps.modulation, b, rtol=1e-6)
    np.testing.assert_allclose(maps.background, a, rtol=1e-6)
    as_float32 = wrapped_phase(images, shift_sign=shift_sign, phase_offset=offset, dtype=np.float32)
    assert as_float32.phase.dtype == as_float32.modulation.dtype == np.float32
    np.testing.assert_array_equal(as_float32.phase, maps.phase.astype(np.float32))


def test_float32_arctangent_over_every_direction():
    # Directions all round the circle, on the axes and near the wrap, magnitudes from 1e-3 to 1e4 and 0.
    angle = np.concatenate([np.linspace(0, 2 * np.pi, 4001), [-1e-9, 1e-9, np.pi / 2, np.pi, 1.5 * np.pi]])
    radius = np.geomspace(1e-3, 1e4, angle.size)
    sine = (radius * np.sin(angle)).astype(np.float32)[None]
    cosine = (radius * np.cos(angle)).astype(np.float32)[None]
    magnitude = np.hypot(sine, cosine)
    ours = angle_0_2pi_float32(sine, cosine, magnitude)
    exact = np.mod(np.arctan2(sine.astype(np.float64), cosine.astype(np.float64)), 2 * np.pi)
    assert ours.dtype == np.float32 and ours.min() >= 0 and ours.max() < 2 * np.pi
    assert np.abs(wrapped_difference(ours, exact)).max() < 5e-7
    zero = np.zeros((1, 1), np.float32)
    assert angle_0_2pi_float32(zero, zero, zero)[0, 0] == 0.0


def test_quality_mask_saturation_in_any_frame_of_sixteen_bit():
    images = np.full((3, 4, 5), 1000, np.uint16)
    images[2, 1, 1] = 65535
    images[0, 3, 4] = 65534
    mask = quality_mask(images, np.full((4, 5), 50.0), min_modulation=10.0)
    assert mask.sum() == 19 and not mask[1, 1]
    assert not quality_mask(images, np.full((4, 5), 50.0), min_modulation=10.0, saturation_level=65534)[3, 4]


@pytest.mark.parametrize("steps", [4, 40])
def test_float64_path_in_blocks_equals_the_formula(steps):
    # Float images: float64 sums, in several pixel blocks (19200 px; 2048 px per block at 40 steps).
    rng = np.random.default_rng(2)
    phase, background, modulation = smooth_scene(120, 160)
    images = synthetic_stack(phase, background, modulation, steps, -1, 0.3) + rng.normal(0, 2.0, (steps, 120, 160))
    maps = wrapped_phase(images, phase_offset=0.3)
    psi, b, a = reference_maps(images, -1, 0.3)
    assert np.abs(wrapped_difference(maps.phase, psi)).max() < 1e-12
    np.testing.assert_allclose(maps.modulation, b, rtol=1e-12)
    np.testing.assert_allclose(maps.background, a, rtol=1e-12)
