"""Tests for dptpu.fpp.graycode: plain and complementary Gray code + phase shifting."""

import numpy as np
import pytest

from dptpu.fpp.graycode import (
    GrayCodePatterns,
    decode_graycode,
    graycode_patterns,
    unwrap_graycode,
)

PERIOD = 16.0  # projector pixels per code step = per phase period
BITS = 6  # 64 code steps * 16 px = 1024 >= the 912 px projector extent
HEIGHT, WIDTH = 120, 160


def scene_projector_x():
    """(H, W) projector coordinate seen by each camera pixel: six bands of shifted/scaled ramps.

    The bands jump by many periods from one to the next (depth discontinuities) and the slope
    differs per band, so every code step boundary is crossed at varied sub-period positions.
    """
    u = np.arange(WIDTH, dtype=np.float64)
    offsets = [20.3, 400.7, 95.1, 700.9, 250.45, 130.2]
    slopes = [5.13, 2.71, 3.9, 1.23, 4.07, -0.61]
    band = np.arange(HEIGHT) * len(offsets) // HEIGHT  # (H,)
    x_p = np.array(offsets)[band][:, None] + np.array(slopes)[band][:, None] * u[None, :]
    return x_p  # (H, W) in [~20, ~900]


def gray_bits_at(x_p, *, complementary=False):
    """Ideal 0/1 pattern values at continuous projector coordinate x_p, independent of the module.

    Plain: bit BITS-1-b of the Gray code of floor(x_p / PERIOD), shape (BITS, ...).
    Complementary: floor(x_p / PERIOD + 1/2) mod 2, shape (...).
    """
    if complementary:
        return (np.floor(x_p / PERIOD + 0.5).astype(np.int64) % 2).astype(np.float64)
    code = np.floor(x_p / PERIOD).astype(np.int64)
    gray = code ^ (code >> 1)
    return np.stack([((gray >> (BITS - 1 - b)) & 1).astype(np.float64) for b in range(BITS)])


def blurred_bits_at(x_p, *, complementary=False, half_width=0.3 * PERIOD, samples=61):
    """Box blur of the binary patterns over x_p +- half_width (a defocused projector)."""
    offsets = np.linspace(-half_width, half_width, samples)
    total = 0.0
    for offset in offsets:  # loop over blur samples, not pixels
        total = total + gray_bits_at(x_p + offset, complementary=complementary)
    return total / samples


def camera_images(bit_values, albedo, ambient):
    """Camera intensity of pattern values in [0, 1] on a surface of albedo, plus ambient light."""
    return ambient + albedo * 200.0 * bit_values


def wrapped_of(x_p):
    psi = np.mod(2 * np.pi * x_p / PERIOD, 2 * np.pi)
    psi[psi >= 2 * np.pi] = 0.0
    return psi


def scene_photometry():
    v, u = np.mgrid[0:HEIGHT, 0:WIDTH]
    albedo = 0.35 + 0.6 * (0.5 + 0.5 * np.sin(u / 13.0 + v / 17.0))  # (H, W) in [0.35, 0.95]
    ambient = 10.0 + 5.0 * np.cos(v / 23.0)  # (H, W)
    return albedo, ambient


def references(bits, comp, albedo, ambient):
    """Camera images for plain bits, inverses, complementary bit and its inverse, white, black."""
    return dict(
        images=camera_images(bits, albedo, ambient),
        inverse=camera_images(1.0 - bits, albedo, ambient),
        complementary=camera_images(comp, albedo, ambient),
        complementary_inverse=camera_images(1.0 - comp, albedo, ambient),
        white=camera_images(np.ones_like(comp), albedo, ambient),
        black=camera_images(np.zeros_like(comp), albedo, ambient),
    )


def unwrap(psi, captured, *, mode, complementary):
    kwargs = dict(period=PERIOD)
    if mode == "inverse":
        kwargs["inverse"] = captured["inverse"]
        if complementary:
            kwargs["complementary_inverse"] = captured["complementary_inverse"]
    else:
        kwargs["white"], kwargs["black"] = captured["white"], captured["black"]
    if complementary:
        kwargs["complementary"] = captured["complementary"]
    return unwrap_graycode(psi, captured["images"], **kwargs)


def test_patterns_match_the_gray_sequence():
    patterns = graycode_patterns(3, 1, (8, 2), inverse=True, complementary=False)
    assert isinstance(patterns, GrayCodePatterns)
    assert patterns.images.shape == (3, 2, 8) and patterns.images.dtype == np.uint8
    # Gray codes of 0..7: 000 001 011 010 110 111 101 100, MSB first.
    expected = np.array(
        [[0, 0, 0, 0, 1, 1, 1, 1], [0, 0, 1, 1, 1, 1, 0, 0], [0, 1, 1, 0, 0, 1, 1, 0]]
    )
    np.testing.assert_array_equal(patterns.images[:, 1, :], 255 * expected)
    np.testing.assert_array_equal(patterns.inverse, 255 - patterns.images)
    assert patterns.complementary is None and patterns.complementary_inverse is None


def test_complementary_bit_is_shifted_by_half_a_period():
    patterns = graycode_patterns(
        2, 2, (8, 1), complementary=True, inverse=True, bit_depth=16
    )
    assert patterns.complementary.shape == (1, 8) and patterns.complementary.dtype == np.uint16
    # floor(x/2 + 1/2) mod 2 for x = 0..7: transitions in the middle of each 2-px period.
    np.testing.assert_array_equal(
        patterns.complementary[0], 65535 * np.array([0, 1, 1, 0, 0, 1, 1, 0])
    )
    np.testing.assert_array_equal(patterns.complementary_inverse, 65535 - patterns.complementary)
    # Plain LSB has stripes two periods wide:
    # Gray codes of floor(x/2) = 0,0,1,1,2,2,3,3 -> LSB 0,0,1,1,1,1,0,0.
    np.testing.assert_array_equal(patterns.images[1, 0], 65535 * np.array([0, 0, 1, 1, 1, 1, 0, 0]))


def test_patterns_axis_y_and_decode_round_trip():
    patterns = graycode_patterns(5, 3.5, (4, 100), axis="y", inverse=True)
    assert patterns.images.shape == (5, 100, 4)
    code, valid = decode_graycode(patterns.images, inverse=patterns.inverse)
    assert code.dtype == np.int32 and valid.all()
    expected = np.floor(np.arange(100) / 3.5).astype(np.int32)
    np.testing.assert_array_equal(code, np.broadcast_to(expected[:, None], (100, 4)))


def test_too_few_bits_for_the_projector_raises():
    message = "bits=5 encode 32 code steps but .* needs 57; use bits >= 6"
    with pytest.raises(ValueError, match=message):
        graycode_patterns(5, 16, (912, 1140))


@pytest.mark.parametrize("mode", ["inverse", "white_black"])
@pytest.mark.parametrize("complementary", [False, True])
def test_noiseless_scene_recovers_every_fringe_order(mode, complementary):
    x_p = scene_projector_x()
    albedo, ambient = scene_photometry()
    captured = references(
        gray_bits_at(x_p), gray_bits_at(x_p, complementary=True), albedo, ambient
    )
    result = unwrap(wrapped_of(x_p), captured, mode=mode, complementary=complementary)
    expected_order = np.floor(x_p / PERIOD).astype(np.int32)
    assert result.fringe_order.dtype == np.int32
    np.testing.assert_array_equal(result.fringe_order, expected_order)
    assert result.valid.all()
    assert np.abs(result.absolute_phase - 2 * np.pi * x_p / PERIOD).max() < 1e-9
    # Twice the distance (periods) to the used code's transition: plain spans [0, 1],
    # complementary never comes closer than a quarter period.
    assert result.reliability.min() >= (0.5 if complementary else 0.0)
    assert result.reliability.max() <= 1.0


def test_decode_with_white_black_and_threshold_and_shadow_is_invalid():
    x_p = scene_projector_x()
    albedo, ambient = scene_photometry()
    albedo[:10, :20] = 0.0  # shadow: the projector does not reach these pixels
    captured = references(gray_bits_at(x_p), gray_bits_at(x_p, complementary=True), albedo, ambient)
    expected = np.floor(x_p / PERIOD).astype(np.int32)
    code, valid = decode_graycode(
        captured["images"], white=captured["white"], black=captured["black"]
    )
    lit = np.ones((HEIGHT, WIDTH), bool)
    lit[:10, :20] = False
    np.testing.assert_array_equal(valid, lit)
    np.testing.assert_array_equal(code[lit], expected[lit])
    threshold = ambient + albedo * 100.0
    code_t, valid_t = decode_graycode(captured["images"], threshold=threshold)
    np.testing.assert_array_equal(code_t[lit], expected[lit])
    np.testing.assert_array_equal(valid_t, lit)


def blurred_capture(seed=0, phase_noise_rad=0.15, intensity_noise=2.0):
    rng = np.random.default_rng(seed)
    x_p = scene_projector_x()
    albedo, ambient = scene_photometry()
    captured = references(
        blurred_bits_at(x_p), blurred_bits_at(x_p, complementary=True), albedo, ambient
    )
    for key in captured:
        captured[key] = captured[key] + rng.normal(0.0, intensity_noise, captured[key].shape)
    psi = wrapped_of(x_p + PERIOD * rng.normal(0.0, phase_noise_rad, x_p.shape) / (2 * np.pi))
    # The right order is the one that puts psi + 2 pi k within pi of the true phase.
    true_order = np.round((2 * np.pi * x_p / PERIOD - psi) / (2 * np.pi)).astype(np.int32)
    return psi, captured, true_order


@pytest.mark.parametrize("mode", ["inverse", "white_black"])
def test_blur_plain_gray_code_fails_at_boundaries_complementary_does_not(mode):
    psi, captured, true_order = blurred_capture()
    plain = unwrap(psi, captured, mode=mode, complementary=False)
    plain_errors = plain.fringe_order != true_order
    assert plain_errors.mean() > 0.01
    # The errors sit where psi is near the wrap: within 4 sigma of phase noise (0.095 period),
    # i.e. reliability (twice the distance in periods) below 0.2.
    assert plain.reliability[plain_errors].max() < 0.2
    comp = unwrap(psi, captured, mode=mode, complementary=True)
    assert np.count_nonzero(comp.fringe_order != true_order) == 0
    assert comp.valid.all()
    assert comp.reliability.min() >= 0.5


def test_pixelated_projector_complementary_exact_plain_errs_in_half_pixel_band():
    """Camera samples the real projector patterns at the nearest projector pixel.

    With phase 0 at the centre of projector pixel 0, projector pixel m*PERIOD (code m) covers
    [m*PERIOD - 0.5, m*PERIOD + 0.5): its left half still has psi near 2*pi, so a pixelated plain
    Gray code is off by one order on that half-pixel band; complementary Gray code is exact.
    """
    x_p = scene_projector_x()
    albedo, ambient = scene_photometry()
    patterns = graycode_patterns(BITS, PERIOD, (912, 4), inverse=True, complementary=True)
    column = np.clip(np.rint(x_p).astype(int), 0, 911)  # nearest projector pixel, (H, W)
    captured = dict(
        images=camera_images(patterns.images[:, 0, :][:, column] / 255.0, albedo, ambient),
        inverse=camera_images(patterns.inverse[:, 0, :][:, column] / 255.0, albedo, ambient),
        complementary=camera_images(patterns.complementary[0, column] / 255.0, albedo, ambient),
        complementary_inverse=camera_images(
            patterns.complementary_inverse[0, column] / 255.0, albedo, ambient
        ),
    )
    psi = wrapped_of(x_p)
    true_order = np.floor(x_p / PERIOD).astype(np.int32)
    plain = unwrap(psi, captured, mode="inverse", complementary=False)
    in_band = np.mod(x_p, PERIOD) >= PERIOD - 0.5
    np.testing.assert_array_equal(plain.fringe_order != true_order, in_band)
    assert in_band.mean() > 0.02
    comp = unwrap(psi, captured, mode="inverse", complementary=True)
    np.testing.assert_array_equal(comp.fringe_order, true_order)
    # The same captures as 8-bit camera images (unsigned differences must not wrap around).
    captured_8bit = {key: np.rint(value).astype(np.uint8) for key, value in captured.items()}
    comp_8bit = unwrap(psi, captured_8bit, mode="inverse", complementary=True)
    np.testing.assert_array_equal(comp_8bit.fringe_order, true_order)
    assert comp_8bit.valid.all()
    code, valid = decode_graycode(captured_8bit["images"], inverse=captured_8bit["inverse"])
    np.testing.assert_array_equal(code, np.floor(np.rint(x_p) / PERIOD))
    assert valid.all()


def test_unwrap_accepts_phase_maps_and_marks_nan_invalid():
    from dptpu.fpp.phase import WrappedPhase

    x_p = scene_projector_x()
    albedo, ambient = scene_photometry()
    captured = references(gray_bits_at(x_p), gray_bits_at(x_p, complementary=True), albedo, ambient)
    psi = wrapped_of(x_p)
    psi[5, 7] = np.nan
    maps = WrappedPhase(phase=psi, modulation=np.ones_like(psi), background=np.ones_like(psi))
    result = unwrap_graycode(maps, captured["images"], period=PERIOD, inverse=captured["inverse"])
    assert not result.valid[5, 7] and np.isnan(result.absolute_phase[5, 7])
    assert result.reliability[5, 7] == 0.0 and result.fringe_order[5, 7] == 0
    assert result.valid.sum() == HEIGHT * WIDTH - 1
    mask = np.ones((HEIGHT, WIDTH), bool)
    mask[:, :3] = False
    masked = unwrap_graycode(
        maps, captured["images"], period=PERIOD, inverse=captured["inverse"], valid=mask
    )
    assert masked.valid.sum() == HEIGHT * (WIDTH - 3) - 1
    assert np.isnan(masked.absolute_phase[:, :3]).all()


def test_bad_input_raises_naming_the_problem():
    images = np.zeros((4, 8, 10))
    with pytest.raises(ValueError, match="give exactly one binarization reference"):
        decode_graycode(images)
    with pytest.raises(ValueError, match="give exactly one binarization reference"):
        decode_graycode(images, inverse=images, threshold=0.5)
    with pytest.raises(ValueError, match="white and black references must be given together"):
        decode_graycode(images, white=np.ones((8, 10)))
    with pytest.raises(ValueError, match=r"inverse must have the shape of images \(4, 8, 10\)"):
        decode_graycode(images, inverse=np.zeros((3, 8, 10)))
    with pytest.raises(ValueError, match=r"images must have shape \(bits, H, W\).*got \(8, 10\)"):
        decode_graycode(np.zeros((8, 10)), threshold=0.5)
    bad = images.copy()
    bad[0, 1, 1] = np.nan
    with pytest.raises(ValueError, match="images contain NaN"):
        decode_graycode(bad, threshold=0.5)
    psi = np.zeros((8, 10))
    message = r"\(H, W\) = \(8, 10\) like the wrapped phase; got \(4, 8, 9\)"
    with pytest.raises(ValueError, match=message):
        unwrap_graycode(psi, np.zeros((4, 8, 9)), period=16, threshold=0.5)
    with pytest.raises(ValueError, match="complementary_inverse is required"):
        unwrap_graycode(psi, images, period=16, inverse=images, complementary=psi)
    with pytest.raises(ValueError, match="period must be > 0"):
        unwrap_graycode(psi, images, period=0, threshold=0.5)
    with pytest.raises(ValueError, match=r"wrapped phase must have shape \(H, W\)"):
        unwrap_graycode(images, images, period=16, threshold=0.5)
    message = r"wrapped phase must lie in \[0, 2\*pi\); got values in \[-3"
    with pytest.raises(ValueError, match=message):
        unwrap_graycode(psi - 3.0, images, period=16, threshold=0.5)
    with pytest.raises(ValueError, match="per-bit threshold"):
        unwrap_graycode(psi, images, period=16, threshold=np.ones((4, 1, 1)), complementary=psi)
    with pytest.raises(ValueError, match=r"valid must be a bool array of shape \(8, 10\)"):
        unwrap_graycode(psi, images, period=16, threshold=0.5, valid=np.ones((8, 10)))
