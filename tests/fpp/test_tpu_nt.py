"""Tests for dptpu.fpp.tpu's number-theoretic unwrapping (Eqs. (8)-(9)): the lookup table over the
fringe-order pairs that occur across the projector, nearest-key matching and its noise tolerance, and its
agreement with an exhaustive search over the low order on random frequency pairs and rendered outside rigs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from dptpu.fpp import phase, tpu
from dptpu.sim import outside_rigs

EXTENT_PX = 912.0  # the paper's 912 px projector
F_H, F_L = 64, 10.9  # the paper's NT pair
LAMBDA_H, LAMBDA_L = EXTENT_PX / F_H, EXTENT_PX / F_L  # 14.25 px, 83.67 px
SIGMA_1 = 1.5693  # the paper's 1 sigma camera noise, gray levels


def wrapped(x_p, f):
    return np.mod(2 * np.pi * f * x_p / EXTENT_PX, 2 * np.pi)


def psi_for_key(key_px):
    """(psi_h, psi_l) of shape (1, n) with psi_h = 0, so the measured key is lambda_l*psi_l/(2*pi)."""
    key_px = np.atleast_2d(np.asarray(key_px, dtype=np.float64))
    return np.zeros_like(key_px), 2 * np.pi * key_px / LAMBDA_L


def test_table_lists_exactly_the_pairs_that_occur_across_the_projector():
    table = tpu.nt_lookup_table(F_H, F_L, EXTENT_PX)
    # pairs change at the 64 high and 11 low period starts; only x_p = 0 is shared
    assert table.key_px.size == 64 + 11 - 1
    x_p = np.arange(0.0, EXTENT_PX, 0.01)  # dense: every segment is > 0.3 px long
    dense = set(zip(np.floor(x_p / LAMBDA_H).astype(int), np.floor(x_p / LAMBDA_L).astype(int)))
    assert dense == set(zip(table.k_h.tolist(), table.k_l.tolist()))
    np.testing.assert_allclose(table.key_px, LAMBDA_H * table.k_h - LAMBDA_L * table.k_l, atol=1e-9)
    assert np.all(np.diff(table.key_px) > 0)
    assert -LAMBDA_H < table.key_px.min() and table.key_px.max() < LAMBDA_L
    # smallest gap: 47*lambda_h - 8*lambda_l = 912*(47/64 - 8/10.9) = 0.3922 px
    assert table.tolerance_px == pytest.approx(0.5 * 912 * (47 / 64 - 8 / 10.9), rel=1e-9)
    assert table.tolerance_rad == pytest.approx(2 * np.pi * table.tolerance_px / (LAMBDA_H + LAMBDA_L), rel=1e-12)
    assert table.tolerance_rad == pytest.approx(0.01258, abs=1e-5)


def test_noiseless_ramp_is_exact_with_full_reliability():
    x_p = np.linspace(0.0, EXTENT_PX - 1e-3, 40_000).reshape(100, 400)
    result = tpu.unwrap_nt(wrapped(x_p, F_H), wrapped(x_p, F_L), F_H, F_L, EXTENT_PX)
    np.testing.assert_array_equal(result.fringe_order, np.floor(F_H * x_p / EXTENT_PX))
    assert result.valid.all() and result.n_rejected == 0
    assert result.reliability.min() > 0.999
    np.testing.assert_allclose(result.absolute_phase, 2 * np.pi * F_H * x_p / EXTENT_PX, atol=1e-9)


def test_noise_below_the_tolerance_never_changes_the_order():
    # worst case: d_l = +d, d_h = -d (or the reverse) moves the key by (lambda_l + lambda_h)*d/(2*pi)
    table = tpu.nt_lookup_table(F_H, F_L, EXTENT_PX)
    rng = np.random.default_rng(3)
    shape = (200, 300)
    x_p = rng.uniform(1.0, EXTENT_PX - 1.0, shape)  # at x_p ~ 0 a low-phase wrap leaves the projector
    sign = rng.choice([-1.0, 1.0], shape)
    d = 0.999 * table.tolerance_rad * sign
    psi_h = np.mod(wrapped(x_p, F_H) - d, 2 * np.pi)
    psi_l = np.mod(wrapped(x_p, F_L) + d, 2 * np.pi)
    result = tpu.unwrap_nt(psi_h, psi_l, F_H, F_L, EXTENT_PX)
    # the order that matches the noisy wrapped phase (a wrap of psi_h moves it by one)
    truth = np.rint((2 * np.pi * F_H * x_p / EXTENT_PX - psi_h) / (2 * np.pi))
    np.testing.assert_array_equal(result.fringe_order, truth)
    assert result.valid.all()


def test_tolerance_is_the_decision_boundary_of_the_closest_keys():
    # keys 0 (pair (0, 0)) and 0.3922 px (pair (47, 8)) are the closest; the boundary is at tolerance_px
    table = tpu.nt_lookup_table(F_H, F_L, EXTENT_PX)
    tol = table.tolerance_px
    psi_h, psi_l = psi_for_key([0.0, tol * (1 - 1e-6), tol * (1 + 1e-6), 2 * tol])
    result = tpu.unwrap_nt(psi_h, psi_l, F_H, F_L, EXTENT_PX)
    np.testing.assert_array_equal(result.fringe_order[0], [0, 0, 47, 47])
    np.testing.assert_allclose(result.reliability[0], [1.0, 0.0, 0.0, 1.0], atol=1e-5)


def test_key_outside_every_cell_is_rejected_and_counted():
    # the largest key is 82.232 px (next gap below 1.830 px): keys above 83.147 px are in no cell
    table = tpu.nt_lookup_table(F_H, F_L, EXTENT_PX)
    edge = table.key_px[-1] + 0.5 * (table.key_px[-1] - table.key_px[-2])
    psi_h, psi_l = psi_for_key([edge - 0.01, edge + 0.01, 83.6])
    result = tpu.unwrap_nt(psi_h, psi_l, F_H, F_L, EXTENT_PX)
    assert result.n_rejected == 2
    np.testing.assert_array_equal(result.valid[0], [True, False, False])
    assert result.fringe_order[0, 0] == table.k_h[-1] and (result.fringe_order[0, 1:] == 0).all()
    assert np.isnan(result.absolute_phase[0, 1:]).all() and (result.reliability[0, 1:] == 0).all()


def test_plane_at_one_sigma_three_step_matches_the_gaussian_prediction():
    # A plane across the whole projector, 3-step 8-bit fringes A = B = 127.5 (the full range: the best
    # case), camera noise 1 sigma. Phase noise sqrt(2/3)*sigma/B = 0.0101 rad, key noise
    # s = sigma_phase*hypot(lambda_h, lambda_l)/(2*pi) = 0.136 px against half-gaps of 0.196 to 0.915 px.
    # Predicted share right: mean over pixels of Phi((hi - key)/s) - Phi((lo - key)/s) = 0.9605
    # (measured 0.9597; the rounded key of the old implementation was right on 0.38).
    rng = np.random.default_rng(1)
    x_p = np.repeat(np.linspace(0.5, EXTENT_PX - 0.5, 320)[None, :], 120, axis=0)
    amplitude = 127.5

    def psi(f):
        phi = 2 * np.pi * f * x_p / EXTENT_PX
        frames = np.stack([amplitude + amplitude * np.cos(phi - 2 * np.pi * n / 3) for n in range(3)])
        return phase.wrapped_phase(np.clip(np.rint(frames + rng.normal(0, SIGMA_1, frames.shape)), 0, 255)).phase

    psi_h, psi_l = psi(F_H), psi(F_L)
    result = tpu.unwrap_nt(psi_h, psi_l, F_H, F_L, EXTENT_PX)
    truth = np.rint((2 * np.pi * F_H * x_p / EXTENT_PX - psi_h) / (2 * np.pi))
    accuracy = np.mean(result.fringe_order == truth)

    table = tpu.nt_lookup_table(F_H, F_L, EXTENT_PX)
    s = np.sqrt(2 / 3) * SIGMA_1 / amplitude * np.hypot(LAMBDA_H, LAMBDA_L) / (2 * np.pi)
    key = LAMBDA_H * np.floor(x_p[0] / LAMBDA_H) - LAMBDA_L * np.floor(x_p[0] / LAMBDA_L)
    i = np.searchsorted(table.key_px, key - 1e-9)
    mid = 0.5 * (table.key_px[:-1] + table.key_px[1:])
    lo = np.concatenate([[-np.inf], mid])[i]
    hi = np.concatenate([mid, [np.inf]])[i]
    predicted = np.mean(ndtr((hi - key) / s) - ndtr((lo - key) / s))
    assert predicted == pytest.approx(0.9605, abs=0.002)
    assert abs(accuracy - predicted) < 0.01, (accuracy, predicted)
    assert accuracy > 0.95


def test_ambiguous_pair_raises():
    # 20 and 10 periods: pairs (0, 0) and (2, 1) share the key 0
    with pytest.raises(ValueError, match="ambiguous NT pair.*same key"):
        tpu.nt_lookup_table(20, 10, EXTENT_PX)
    psi = np.zeros((2, 2))
    with pytest.raises(ValueError, match="ambiguous NT pair"):
        tpu.unwrap_nt(psi, psi, 20, 10, EXTENT_PX)
    with pytest.raises(ValueError, match="different frequencies"):
        tpu.nt_lookup_table(16, 16, EXTENT_PX)


# --------------------------------------------------------------------------------------------
# NT on any rig: the lookup decides as an exhaustive search over the low order (issue 16)
# --------------------------------------------------------------------------------------------

LOW_FREQUENCIES = (10.9, 7.3, 12.5, 5.7, 9.1, 11.3)


def exhaustive_search(psi_h, psi_l, f_h, f_l):
    """For each k_l in range(ceil(f_l)): the high phase it predicts, the nearest k_h and the residual (periods).

    Returns the best candidate's (k_h, k_l), its residual and the second best residual, each shaped like psi_h.
    """
    candidates = np.arange(math.ceil(f_l))[:, None, None]  # (M, 1, 1)
    q = (f_h / f_l) * (psi_l + 2 * np.pi * candidates) / (2 * np.pi) - psi_h / (2 * np.pi)  # (M, H, W)
    k_h = np.rint(q)
    residual = np.abs(q - k_h)
    best = np.argmin(residual, axis=0)
    ranked = np.sort(residual, axis=0)
    return np.take_along_axis(k_h, best[None], 0)[0].astype(np.int64), best, ranked[0], ranked[1]


def occurs(table, k_h, k_l):
    """(H, W) bool: the pair (k_h, k_l) is one that occurs on the projector (a table entry)."""
    code = table.k_h.astype(np.int64) * 1000 + table.k_l
    return np.isin(k_h * 1000 + k_l, code)


def test_nt_equals_the_exhaustive_search_on_random_frequency_pairs():
    # f_h 16-120, rational f_l, four projector widths, phase errors up to +-0.05 rad on each phase (the first check
    # holds for any error; the second needs a bound)
    rng = np.random.default_rng(16)
    tested = unambiguous = 0
    for _ in range(60):
        f_h = float(rng.integers(16, 121))
        f_l = float(rng.choice(LOW_FREQUENCIES))
        extent = float(rng.choice([912, 1024, 1280, 1920]))
        try:
            table = tpu.nt_lookup_table(f_h, f_l, extent)
        except ValueError:  # an ambiguous pair (LCM of the periods below the extent): NT refuses it
            continue
        tested += 1
        bound = rng.uniform(0.0, 0.05)
        end = extent * bound / (2 * np.pi * f_l)  # the noise wraps no phase off the projector's ends
        x_p = rng.uniform(end, extent - end, (1, 4000))
        phi_h, phi_l = 2 * np.pi * f_h * x_p / extent, 2 * np.pi * f_l * x_p / extent
        psi_h = np.mod(phi_h + rng.uniform(-bound, bound, x_p.shape), 2 * np.pi)
        psi_l = np.mod(phi_l + rng.uniform(-bound, bound, x_p.shape), 2 * np.pi)
        result = tpu.unwrap_nt(psi_h, psi_l, f_h, f_l, extent)
        k_h, k_l, best, second = exhaustive_search(psi_h, psi_l, f_h, f_l)
        # wherever the search's best candidate is a pair that occurs and beats the second: NT's answer
        decided = occurs(table, k_h, k_l) & (second - best > 1e-9)
        assert result.valid[decided].all(), (f_h, f_l, extent)
        np.testing.assert_array_equal(result.fringe_order[decided], k_h[decided], err_msg=f"{f_h}/{f_l}/{extent}")
        # where the margin exceeds twice the largest residual error ((f_h/f_l + 1) * bound / 2pi periods), the
        # search is unambiguous: its answer is the truth, and so NT's
        clear = second - best > (f_h / f_l + 1) * bound / np.pi
        truth = np.rint((phi_h - psi_h) / (2 * np.pi))
        np.testing.assert_array_equal(result.fringe_order[clear], truth[clear])
        assert decided[clear].all()
        unambiguous += int(clear.sum())
    assert tested >= 30
    assert unambiguous > 0.3 * tested * 4000, unambiguous


@pytest.mark.parametrize("rig_seed, f_h, f_l", [(None, 88.0, 10.9), (0, 64.0, 7.3), (4, 42.0, 10.9),
                                                (6, 44.0, 12.5)])
def test_nt_equals_the_exhaustive_search_on_rendered_outside_rigs(rig_seed, f_h, f_l):
    # 12 noiseless steps (8-bit) on rigs unlike the project's, two spheres before a tilted plane, 3x3 supersampled:
    # mixed pixels at the depth edges. None: the outside tester's rig of issue 16 (1800 px, 150 mm, 14 deg).
    rig = outside_rigs.issue16_rig() if rig_seed is None else outside_rigs.random_outside_rig(rig_seed)
    capture = outside_rigs.render_phases(rig, outside_rigs.spheres_and_plane(rig, seed=rig_seed or 0), [f_h, f_l],
                                         steps=12)
    psi_h, psi_l = capture.phases[f_h], capture.phases[f_l]
    valid = capture.valid & (capture.modulation[f_h] > 5.1) & (capture.modulation[f_l] > 5.1)
    result = tpu.unwrap_nt(psi_h, psi_l, f_h, f_l, capture.extent, valid=valid)
    table = tpu.nt_lookup_table(f_h, f_l, capture.extent)
    k_h, k_l, best, second = exhaustive_search(psi_h, psi_l, f_h, f_l)
    decided = valid & occurs(table, k_h, k_l) & (second - best > 1e-9)
    np.testing.assert_array_equal(result.fringe_order[decided], k_h[decided])
    assert result.valid[decided].all()
    truth = capture.order(f_h)
    nt_right, search_right = (result.fringe_order == truth) & valid, (k_h == truth) & valid
    assert not (search_right & ~nt_right).any()  # NT is right wherever the search is
    assert nt_right.sum() > 0.97 * valid.sum()  # measured 98.5-99.6 %: wrong only at mixed pixels
