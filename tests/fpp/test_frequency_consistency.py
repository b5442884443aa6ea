"""Agreement of a two-frequency capture's phases (dptpu.fpp.frequency_consistency)."""
import numpy as np
import pytest

from dptpu.fpp.confidence import DEFAULT_MIN_CONFIDENCE
from dptpu.fpp.frequency_consistency import (
    DEFAULT_CONSISTENCY_SCALE,
    consistency_residual,
    frequency_consistency,
    quantization_residual_noise,
)
from dptpu.fpp.fringe_noise import quantization_phase_noise
from dptpu.fpp.phase import wrapped_phase

TWO_PI = 2.0 * np.pi


def _capture(f_h, f_l, sigma, shape=(120, 160), seed=0):
    """A plane's absolute phase of f_h (radians) and the low frequency's wrapped phase with Gaussian noise."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.02, 0.97, shape[1])[None, :].repeat(shape[0], 0)  # projector coordinate / width
    absolute = TWO_PI * f_h * x + rng.normal(0, sigma, shape)
    wrapped_low = np.mod(TWO_PI * f_l * x + rng.normal(0, sigma, shape), TWO_PI)
    return absolute, wrapped_low


def test_residual_is_wrapped_into_minus_pi_pi():
    eps = consistency_residual(np.array([0.0, TWO_PI * 64, TWO_PI * 64 + 0.3]), np.array([TWO_PI - 0.1, 0.1, 0.0]),
                               64.0, 63.0)
    assert eps == pytest.approx([0.1, -0.1, 0.3 * 63 / 64], abs=1e-9)  # (63/64) 2 pi 64 = 2 pi 63: a whole turn
    assert np.all((eps > -np.pi) & (eps <= np.pi))


@pytest.mark.parametrize("f_h, f_l", [(64.0, 63.0), (64.0, 1.0), (96.0, 10.9)])
def test_noise_passes_and_a_biased_patch_is_dropped(f_h, f_l):
    sigma = 0.03
    absolute, wrapped_low = _capture(f_h, f_l, sigma)
    # the low phase shifted by 0.3 rad on a patch (light bounced from elsewhere): ~7 sigma of eps, whose sigma is
    # sqrt(1 + (f_l / f_h)^2) 0.03 (a shift of the high phase shows f_l / f_h times smaller)
    wrapped_low[40:60, 50:80] = np.mod(wrapped_low[40:60, 50:80] + 0.3, TWO_PI)
    valid = np.ones(absolute.shape, bool)
    confidence = frequency_consistency(absolute, wrapped_low, f_h, f_l, valid)
    kept = confidence >= DEFAULT_MIN_CONFIDENCE
    rest = valid.copy()
    rest[40:60, 50:80] = False
    # noise: z < 0.8 Z = 5 robust sigma on nearly every pixel (a normal's two-sided tail beyond 5 sigma: 6e-7)
    assert kept[rest].mean() > 0.999
    assert kept[40:60, 50:80].mean() < 0.05


def test_a_wrong_high_order_is_dropped_where_the_noise_is_below_its_step():
    # a wrong order of f_h moves eps by 2 pi f_l / f_h (MF 64/1: 0.098 rad), far above a 0.005 rad noise
    absolute, wrapped_low = _capture(64.0, 1.0, 0.005)
    absolute[10:20, 10:20] += TWO_PI
    confidence = frequency_consistency(absolute, wrapped_low, 64.0, 1.0, np.ones(absolute.shape, bool))
    assert confidence[10:20, 10:20].max() == 0.0
    assert np.median(confidence) > 1 - 1 / DEFAULT_CONSISTENCY_SCALE  # a median pixel: z ~ 0.67


def test_invalid_pixels_and_arguments():
    absolute, wrapped_low = _capture(64.0, 63.0, 0.02, shape=(8, 8))
    valid = np.zeros(absolute.shape, bool)
    assert not frequency_consistency(absolute, wrapped_low, 64.0, 63.0, valid).any()
    valid[2:6, 2:6] = True
    confidence = frequency_consistency(absolute, wrapped_low, 64.0, 63.0, valid)
    assert not confidence[~valid].any() and confidence[valid].min() > 0
    with pytest.raises(ValueError, match="positive"):
        consistency_residual(absolute, wrapped_low, 64.0, 0.0)
    with pytest.raises(ValueError, match="scale"):
        frequency_consistency(absolute, wrapped_low, 64.0, 63.0, valid, scale=0.0)


def _rounded_sequence(x, f, b, steps=12, a=100.3):
    """``steps`` images of a plane at projector coordinate ``x`` (fraction of the width), modulation ``b``, rounded
    to 8 bits and nothing else: ``(wrapped phase, its quantization_phase_noise)``."""
    delta = -TWO_PI * np.arange(steps)[:, None, None] / steps
    images = np.clip(np.rint(a + b * np.cos(TWO_PI * f * x + delta)), 0, 255).astype(np.uint8)
    maps = wrapped_phase(images)
    return maps.phase, quantization_phase_noise(maps.modulation, steps, images.dtype)


@pytest.mark.parametrize("f_h, f_l", [(64.0, 63.0), (64.0, 1.0), (64.0, 10.9)])
def test_a_dim_patch_of_a_clean_capture_is_judged_against_its_own_rounding(f_h, f_l):
    # 12 steps rounded to whole DN, no camera noise: B = 48 DN but 6 DN on a patch (rounding noise 8x the scan's
    # typical one); the patch fails against the scan's s, passes against its own floor; a wrong order of f_h on a
    # bright patch (eps moves by 2 pi f_l / f_h wrapped: 0.098 or 1.07 rad, 40 or more floors) still goes
    x = np.linspace(0.02, 0.97, 160)[None, :] + np.linspace(0, 0.003, 90)[:, None]
    b = np.full(x.shape, 48.0)
    b[10:40, 20:70] = 6.0
    psi_h, noise_h = _rounded_sequence(x, f_h, b)
    psi_l, noise_l = _rounded_sequence(x, f_l, b)
    order = np.floor(f_h * x) + np.round((TWO_PI * f_h * x - np.floor(f_h * x) * TWO_PI - psi_h) / TWO_PI)
    absolute = psi_h + TWO_PI * order  # the right order (psi_h wraps near the period's ends)
    absolute[60:80, 100:140] += TWO_PI  # one order off
    valid = np.ones(x.shape, bool)
    dim, wrong = np.zeros(x.shape, bool), np.zeros(x.shape, bool)
    dim[10:40, 20:70], wrong[60:80, 100:140] = True, True
    floor = quantization_residual_noise(noise_h, noise_l, f_h, f_l)
    expected = np.hypot(f_l / f_h, 1.0) * np.sqrt(2.0 / 12) / (np.sqrt(12.0) * b)
    assert floor == pytest.approx(expected, rel=0.05)
    without = frequency_consistency(absolute, psi_l, f_h, f_l, valid) >= DEFAULT_MIN_CONFIDENCE
    kept = frequency_consistency(absolute, psi_l, f_h, f_l, valid, floor=floor) >= DEFAULT_MIN_CONFIDENCE
    assert without[dim].mean() < 0.7  # the scan's s alone drops about half of the dim patch
    assert kept[dim].all() and kept[~dim & ~wrong].all()
    assert not kept[wrong].any()
    assert quantization_residual_noise(None, noise_l, f_h, f_l) is None
    no_modulation = np.where(dim, np.inf, floor)  # B = 0: no floor (the scan's s) rather than anything passing
    assert np.array_equal(frequency_consistency(absolute, psi_l, f_h, f_l, valid, floor=no_modulation)[dim],
                          frequency_consistency(absolute, psi_l, f_h, f_l, valid)[dim])
