"""fpp.region_consistency: patches one order off that no single pixel can tell, found by their median, and kept where
the published order is right whatever the classical order says."""
import numpy as np
import pytest

from dptpu.fpp.region_consistency import MIN_TEST_PIXELS, order_error_estimate, rejected_regions

F_H, F_L = 64.0, 63.0  # MW: delta = -1/64, a wrong order moves the low phase by 2 pi / 64 only
SHAPE = (60, 80)


def _phases(true_periods: np.ndarray, published_order: np.ndarray, noise_orders: float, rng):
    """``(published absolute phase of f_h, wrapped low phase)`` of a surface at ``true_periods`` (absolute phase of
    f_h in periods), the low phase with Gaussian noise of ``noise_orders`` orders of ``r``."""
    psi_h = 2.0 * np.pi * np.mod(true_periods, 1.0)
    absolute = psi_h + 2.0 * np.pi * published_order
    noise_rad = noise_orders * 2.0 * np.pi / F_H  # r = eps / (2 pi delta), |delta| = 1 / 64
    psi_l = np.mod(2.0 * np.pi * (F_L / F_H) * true_periods + rng.normal(0.0, noise_rad, true_periods.shape),
                   2.0 * np.pi)
    return absolute, psi_l


def _ramp() -> np.ndarray:
    rows, cols = np.indices(SHAPE)
    return 5.0 + 0.15 * cols + 0.02 * rows  # periods: fringes of ~6.7 px


def test_order_error_estimate_is_the_order_error_in_orders():
    true = _ramp()
    for error in (-3, -1, 0, 1, 2):
        absolute, psi_l = _phases(true, np.floor(true) + error, 0.0, np.random.default_rng(0))
        r = order_error_estimate(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool))
        np.testing.assert_allclose(r, error, atol=1e-3)  # float32
    # MF and NT: the same estimate from their own delta (1/64 and 10.9/64)
    for f_l in (1.0, 10.9):
        absolute = 2.0 * np.pi * (true + 1.0)
        psi_l = np.mod(2.0 * np.pi * (f_l / F_H) * true, 2.0 * np.pi)
        np.testing.assert_allclose(order_error_estimate(absolute, psi_l, F_H, f_l, np.ones(SHAPE, bool)), 1.0,
                                   atol=1e-3)


def test_strip_one_order_off_behind_a_phase_continuous_step_is_rejected():
    """A depth step 0.95 period deep: the far side's published order is one less, so its published phase runs on
    across the step (-0.05 period); r is -1 there under noise of 0.6 order a pixel (the twin's 2 sigma)."""
    true = _ramp()
    strip = np.zeros(SHAPE, bool)
    strip[30:40, 20:60] = True  # 400 px beyond the step
    true = np.where(strip, true + 0.95, true)
    published = np.floor(true) - strip  # continuous: the far side one order low
    published_periods = published + np.mod(true, 1.0)
    assert np.abs(np.diff(published_periods, axis=0)[29, 20:60]).max() < 0.1  # no step in the published phase
    for seed in range(3):
        absolute, psi_l = _phases(true, published, 0.6, np.random.default_rng(seed))
        rejected = rejected_regions(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool))
        assert rejected[strip].mean() > 0.6, seed  # the proposal window erodes the strip's edges
        rows, cols = np.nonzero(rejected & ~strip)
        # outside the strip: at most pixels within the proposal radius (3) of it
        assert np.all((rows >= 27) & (rows < 43) & (cols >= 17) & (cols < 63)), seed


def test_patch_where_the_network_is_right_against_a_wrong_prior_is_kept():
    """3-step-like noise of 1.5 orders a pixel: the classical order (rounded r) is wrong on ~74 % of the pixels,
    the published order is right everywhere; nothing is rejected."""
    true = _ramp()
    for seed in range(5):
        absolute, psi_l = _phases(true, np.floor(true), 1.5, np.random.default_rng(seed))
        r = order_error_estimate(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool))
        assert np.mean(np.rint(r) != 0) > 0.6  # the classical order is mostly wrong
        assert not rejected_regions(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool)).any(), seed


def test_right_orders_are_kept_at_every_noise_level_and_a_wrong_patch_found_among_them():
    rng = np.random.default_rng(7)
    true = _ramp()
    for noise in (0.05, 0.3, 0.6, 1.0):
        absolute, psi_l = _phases(true, np.floor(true), noise, rng)
        assert not rejected_regions(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool)).any(), noise
    patch = np.zeros(SHAPE, bool)
    patch[10:22, 50:62] = True  # 144 px, two orders high, no step at all
    absolute, psi_l = _phases(true, np.floor(true) + 2 * patch, 0.6, rng)
    rejected = rejected_regions(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool))
    assert rejected[patch].mean() > 0.6 and not rejected[:, :40].any()


def test_too_few_test_pixels_or_invalid_pixels_reject_nothing():
    true = _ramp()
    tiny = np.zeros(SHAPE, bool)
    tiny[5:8, 5:8] = True  # 9 px: fewer than MIN_TEST_PIXELS on either half
    assert tiny.sum() < 2 * MIN_TEST_PIXELS
    absolute, psi_l = _phases(true, np.floor(true) - tiny, 0.1, np.random.default_rng(1))
    assert not rejected_regions(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool)).any()
    strip = np.zeros(SHAPE, bool)
    strip[30:40, 20:60] = True
    absolute, psi_l = _phases(true, np.floor(true) - strip, 0.1, np.random.default_rng(1))
    valid = ~strip  # the wrong strip is not valid: nothing to judge
    assert not rejected_regions(absolute, psi_l, F_H, F_L, valid).any()
    assert not rejected_regions(absolute, psi_l, F_H, F_L, np.zeros(SHAPE, bool)).any()


def test_checks():
    absolute, psi_l = np.zeros(SHAPE), np.zeros(SHAPE)
    with pytest.raises(ValueError, match="not a whole number"):
        order_error_estimate(absolute, psi_l, 64.0, 32.0 * 4, np.ones(SHAPE, bool))
    with pytest.raises(ValueError, match="valid must have"):
        order_error_estimate(absolute, psi_l, F_H, F_L, np.ones((2, 2), bool))
    with pytest.raises(ValueError, match="radius >= 1"):
        rejected_regions(absolute, psi_l, F_H, F_L, np.ones(SHAPE, bool), radius=0)
