"""Near-twins of NT frequency pairs (fpp.nt_twins): the analytic twin set, the per-pixel and per-region decision
against a twin, the warning."""
import math

import numpy as np
import pytest

from dptpu.fpp import tpu
from dptpu.fpp.confidence import DEFAULT_MIN_CONFIDENCE, confident
from dptpu.fpp.nt_twins import near_twin_warning, near_twins, reachable_twins, twin_ambiguous

F_H, F_L, EXTENT_PX = 64.0, 10.9, 1024.0


def test_the_nearest_twin_of_64_over_10_9_is_47_orders_away_and_0_029_rad_apart():
    twin = near_twins(F_H, F_L)[0]
    # 10.9 * 47 / 64 = 8.0046875 low periods: 0.0046875 of a period, 0.3 pi / 32 rad
    assert (twin.high_offset, twin.low_offset) == (47, 8)
    assert twin.separation_rad == pytest.approx(0.3 * math.pi / 32, rel=1e-9)
    assert twin.share == pytest.approx(17 / 64)
    # the next: 41 orders (10.9 * 41 / 64 = 6.98281: -0.01719 of a period)
    assert near_twins(F_H, F_L)[1].high_offset == 41
    assert near_twins(F_H, F_L)[1].separation_rad == pytest.approx(2 * math.pi * (10.9 * 41 / 64 - 7), rel=1e-9)


def test_the_nearest_twin_of_60_over_10_9_is_11_orders_away():
    # 10.9 * 11 / 60 = 1.99833 low periods: -1 / 600 of a period, -pi / 300 rad, over 49 / 60 of the projector
    twin = near_twins(60.0, F_L)[0]
    assert (twin.high_offset, twin.low_offset) == (11, 2)
    assert twin.separation_rad == pytest.approx(-math.pi / 300, rel=1e-9)
    assert twin.share == pytest.approx(49 / 60)


def test_every_twin_predicts_the_low_phase_it_states():
    # the low phase Eq. (3) predicts at (k_h + m, k_l + n) minus the one at (k_h, k_l), for every listed twin
    for f_h, f_l in ((64.0, 10.9), (88.0, 10.9), (37.0, 5.3)):
        twins = near_twins(f_h, f_l)
        assert len(twins) == math.ceil(f_h) - 1
        for twin in twins:
            shift = 2 * math.pi * (f_l / f_h * twin.high_offset - twin.low_offset)
            assert shift == pytest.approx(twin.separation_rad, abs=1e-12)
            assert abs(twin.separation_rad) <= math.pi


def test_reach_is_the_boundary_half_way_within_z_sigma():
    # the 47-twin's boundary lies 0.01473 rad from the order: reached by 4 sigma of 0.0037 rad, not of 0.0036
    assert [t.high_offset for t in reachable_twins(F_H, F_L, 0.0037)] == [47]
    assert reachable_twins(F_H, F_L, 0.0036) == ()


def test_warning_names_offset_separation_and_share_only_within_reach():
    text = near_twin_warning(F_H, F_L, 0.012)
    assert text is not None and "\n" not in text
    assert "47 high orders (8 low)" in text and "0.029 rad" in text and "the first and the last 26.6 %" in text
    assert near_twin_warning(F_H, F_L, 0.002) is None  # a noiseless capture: 7 sigma from the boundary


def _ramp(shape, rng, noise_rad):
    """A plane across the whole projector (columns), wrapped phases with Gaussian phase noise; truth x / W."""
    x = np.broadcast_to(np.linspace(0.0005, 0.9995, shape[1]), shape)
    psi_h = np.mod(2 * np.pi * F_H * x + rng.normal(0, noise_rad, shape), 2 * np.pi)
    psi_l = np.mod(2 * np.pi * F_L * x + rng.normal(0, noise_rad, shape), 2 * np.pi)
    return x, psi_h, psi_l


def test_twins_of_noisy_pixels_get_no_confidence_and_far_pixels_keep_theirs():
    # 0.01 rad phase noise: the classical lookup lands on the 47-twin on ~7 % of the pixels that have it (the first
    # and the last 17/64 of the projector), nowhere else
    rng = np.random.default_rng(5)
    x, psi_h, psi_l = _ramp((60, 1200), rng, 0.01)
    result = tpu.unwrap_nt(psi_h, psi_l, F_H, F_L, EXTENT_PX)
    shift = np.rint((result.absolute_phase - 2 * np.pi * F_H * x) / (2 * np.pi))
    band = (x > 47 / 64) | (x < 17 / 64)
    wrong = result.valid & (shift != 0)
    assert np.all(np.abs(shift[wrong]) == 47)
    assert 0.03 < wrong[band].mean() < 0.2 and not wrong[~band].any()
    ambiguous = twin_ambiguous(result.absolute_phase, psi_l, F_H, F_L, result.valid)
    kept, _ = confident(np.where(ambiguous, 0.0, result.reliability), result.valid, DEFAULT_MIN_CONFIDENCE)
    assert not (kept & wrong).any()  # not one twin published by default
    assert not ambiguous[~band].any()  # far from the twin: the confidence is unchanged
    # the band's right pixels: their regions (one low order each, thousands of pixels) tell the twins apart
    assert ambiguous[band & ~wrong].mean() < 0.01


def test_a_region_decided_as_the_twin_is_ambiguous_as_a_whole():
    # a whole patch of the band published 47 orders low (a band prior that took the twin), at 0.01 rad: every pixel
    # of it loses its confidence; the band's right regions keep theirs
    rng = np.random.default_rng(6)
    x, psi_h, psi_l = _ramp((60, 1200), rng, 0.01)
    order = np.rint((2 * np.pi * F_H * x - psi_h) / (2 * np.pi))  # the right order of the noisy wrapped phase
    patch = np.zeros(x.shape, bool)
    patch[10:50, 1000:1150] = True  # true low order 10 (x / W 0.83-0.96)
    published = np.where(patch, order - 47, order)
    absolute = psi_h + 2 * np.pi * published
    ambiguous = twin_ambiguous(absolute, psi_l, F_H, F_L, np.ones(x.shape, bool))
    assert ambiguous[patch].all()
    assert not twin_ambiguous(absolute, psi_l, F_L, F_H, np.ones(x.shape, bool)).any()  # not an NT pair f_h > f_l
    band = ((x > 47 / 64) | (x < 17 / 64)) & ~patch
    assert ambiguous[band].mean() < 0.01 and not ambiguous[(x > 17 / 64 + 0.01) & (x < 47 / 64 - 0.01)].any()


def test_a_region_that_mixes_two_twins_is_ambiguous():
    # the band prior's failure seen on an outside capture: one published low order over pixels of two true ones
    # (true low order 9 published 41 orders low, true 10 published 47 low: low order 2 for both)
    rng = np.random.default_rng(7)
    x, psi_h, psi_l = _ramp((60, 1200), rng, 0.02)
    order = np.rint((2 * np.pi * F_H * x - psi_h) / (2 * np.pi))
    low = np.floor(F_L * x)
    patch = np.zeros(x.shape, bool)
    patch[5:55, 1050:1150] = True  # x / W 0.875-0.958: the low order steps from 9 to 10 at x / W = 10 / 10.9
    published = np.where(patch, order - np.where(low >= 10, 47, 41), order)
    absolute = psi_h + 2 * np.pi * published
    low_published = np.rint((F_L / F_H * absolute - psi_l)[patch] / (2 * np.pi))
    assert np.mean(low_published == 2) > 0.98  # (a noisy low phase at its wrap: a few pixels one low order off)
    ambiguous = twin_ambiguous(absolute, psi_l, F_H, F_L, np.ones(x.shape, bool))
    assert ambiguous[patch].mean() > 0.99


def test_a_dim_region_of_one_surface_that_its_region_tells_from_the_twin_keeps_its_confidence():
    # the stripe of low order 9 (x / W 0.826-0.917, in the 47-twin's band) at a third of the modulation: three times
    # the phase noise of the rest (0.02 -> 0.06 rad). Its region (8 x 110 pixels, all right) clears the twin's
    # boundary by z = 0.01473 sqrt(880) / (sqrt(pi / 2) 0.061) = 5.7 standard errors, and its spread is the one its
    # modulation predicts (one surface, not a mixture): decided as a whole, none of it ambiguous. (Judged in windows
    # sized by the scan's noise, 11 x 8 pixels at 0.061 rad: 2.3 standard errors, most pixels would be dropped.)
    rng = np.random.default_rng(8)
    shape = (8, 1200)
    x = np.broadcast_to(np.linspace(0.0005, 0.9995, shape[1]), shape)
    dim = (np.floor(F_L * x) == 9)
    noise = np.where(dim, 0.06, 0.02)
    psi_h = np.mod(2 * np.pi * F_H * x + rng.normal(0, 1, shape) * noise, 2 * np.pi)
    psi_l = np.mod(2 * np.pi * F_L * x + rng.normal(0, 1, shape) * noise, 2 * np.pi)
    order = np.rint((2 * np.pi * F_H * x - psi_h) / (2 * np.pi))  # the right order everywhere
    modulation = np.where(dim, 1.0 / 3.0, 1.0)
    ambiguous = twin_ambiguous(psi_h + 2 * np.pi * order, psi_l, F_H, F_L, np.ones(shape, bool),
                               modulation=modulation)
    assert ambiguous[dim].mean() < 0.01
    # the same stripe published 47 orders low (a band prior that took the twin): all of it ambiguous
    published = np.where(dim, order - 47, order)
    ambiguous = twin_ambiguous(psi_h + 2 * np.pi * published, psi_l, F_H, F_L, np.ones(shape, bool),
                               modulation=modulation)
    assert ambiguous[dim].mean() > 0.99
