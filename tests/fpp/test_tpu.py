"""Tests for dptpu.fpp.tpu: temporal phase unwrapping, Eqs. (3)-(9) of the paper."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf

from dptpu.fpp import tpu

EXTENT_PX = 912.0  # projector extent along the fringe axis (the paper's 912 px projector)
HIGH_FREQUENCIES = list(range(16, 97, 4))  # the paper's target domain, step 4
NT_LOW_FREQUENCY = 10.9


def wrapped(x_p, f, extent=EXTENT_PX):
    """Wrapped phase psi = mod(2*pi*f*x_p/W, 2*pi) in [0, 2*pi)."""
    return np.mod(2 * np.pi * f * x_p / extent, 2 * np.pi)


def scene_projector_x(shape=(96, 128), extent=EXTENT_PX):
    """(H, W) projector coordinates of a scene of 12 planar blocks with depth discontinuities.

    Each 32x32 block is a plane ``x_p = mod(a + b*u + c*v, W)`` with seeded offset and slopes, so
    neighbouring blocks jump by hundreds of projector pixels (many fringe periods) and some blocks
    wrap inside. Non-integer coordinates keep pixels off exact period boundaries (checked below).
    """
    rng = np.random.default_rng(0)
    height, width = shape
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    block = (v // 32) * (width // 32) + (u // 32)  # (H, W) block id
    n_blocks = int(block.max()) + 1
    offset = rng.uniform(0.0, extent, n_blocks)
    slope_u = rng.uniform(-6.0, 6.0, n_blocks)
    slope_v = rng.uniform(-3.0, 3.0, n_blocks)
    b = block.astype(int)
    x_p = np.mod(offset[b] + slope_u[b] * (u % 32) + slope_v[b] * (v % 32), extent)
    x_p[0, 0] = 0.0  # the first projector pixel centre
    x_p[-1, -1] = extent - 0.01  # just below the extent
    return x_p


def assert_off_period_boundaries(x_p, frequencies, extent=EXTENT_PX, margin=1e-9):
    """The expected orders floor(f*x_p/W) are well posed: no pixel within 1e-9 of a boundary."""
    for f in frequencies:
        t = f * x_p / extent
        frac = t - np.floor(t)
        assert np.all((x_p == 0) | ((frac > margin) & (frac < 1 - margin))), f


@pytest.fixture(scope="module")
def scene():
    x_p = scene_projector_x()
    used = HIGH_FREQUENCIES + [f - 1 for f in HIGH_FREQUENCIES] + [1.0, NT_LOW_FREQUENCY]
    assert_off_period_boundaries(x_p, used)
    return x_p


def expected_order_and_phase(x_p, f_h):
    return np.floor(f_h * x_p / EXTENT_PX).astype(np.int32), 2 * np.pi * f_h * x_p / EXTENT_PX


def assert_recovers_scene(result, x_p, f_h):
    order, phase = expected_order_and_phase(x_p, f_h)
    assert result.valid.all()
    assert result.fringe_order.dtype == np.int32
    np.testing.assert_array_equal(result.fringe_order, order)
    np.testing.assert_allclose(result.absolute_phase, phase, rtol=0, atol=1e-9)
    assert result.reliability.min() > 0.999


# --- the scene: every method, every frequency of the paper's domain -------------------------


def test_scene_has_depth_discontinuities_covering_the_projector(scene):
    assert scene.min() == 0.0 and scene.max() < EXTENT_PX
    counts, _ = np.histogram(scene, bins=19, range=(0, EXTENT_PX))  # 48 px bins
    assert counts.min() > 0
    # jumps between neighbouring pixels of more than 100 px = more than 10 periods at f_h = 96
    assert np.abs(np.diff(scene, axis=1)).max() > 300
    assert np.count_nonzero(np.abs(np.diff(scene, axis=1)) > 100) >= 50


@pytest.mark.parametrize("f_h", HIGH_FREQUENCIES)
def test_unwrap_mf_recovers_orders_with_unit_low_frequency(scene, f_h):
    result = tpu.unwrap_mf(wrapped(scene, f_h), wrapped(scene, 1.0), f_h, 1.0)
    assert_recovers_scene(result, scene, f_h)


@pytest.mark.parametrize("f_h", [16, 64, 96])
def test_unwrap_mf_float32_recovers_orders_of_float32_maps(scene, f_h):
    psi_h, psi_l = wrapped(scene, f_h).astype(np.float32), wrapped(scene, 1.0).astype(np.float32)
    result = tpu.unwrap_mf_float32(psi_h, psi_l, f_h, 1.0)
    order, phase = expected_order_and_phase(scene, f_h)
    assert result.valid.all() and result.fringe_order.dtype == np.int32
    assert result.absolute_phase.dtype == result.reliability.dtype == np.float32
    np.testing.assert_array_equal(result.fringe_order, order)
    # float32 maps in (2.4e-7 rad) and float32 out: 2 ulps of 2*pi*f_h (3.1e-5 rad at f_h = 96)
    ulp = np.spacing(np.float32(2 * np.pi * f_h))
    assert np.abs(result.absolute_phase - phase).max() <= 2 * ulp
    assert result.reliability.min() > 0.999


def test_unwrap_mf_float32_matches_float64_away_from_half_integers(scene):
    rng = np.random.default_rng(0)
    f_h = 64

    def noise():
        return rng.normal(0.0, 0.05, scene.shape)  # rad: q near half-integers

    psi_h = np.mod(wrapped(scene, f_h) + noise(), 2 * np.pi).astype(np.float32)
    psi_l = np.mod(wrapped(scene, 1.0) + noise(), 2 * np.pi).astype(np.float32)
    psi_h[psi_h >= 2 * np.pi] = 0.0
    psi_l[psi_l >= 2 * np.pi] = 0.0
    psi_h[5, 7] = np.nan
    exact = tpu.unwrap_mf(psi_h, psi_l, f_h)  # float64 on the same float32 maps
    fast = tpu.unwrap_mf_float32(psi_h, psi_l, f_h)
    np.testing.assert_array_equal(fast.valid, exact.valid)
    assert not fast.valid[5, 7] and np.isnan(fast.absolute_phase[5, 7]) and fast.fringe_order[5, 7] == 0
    # q in float32 within 1.4e-5 of float64 (the docstring's bound): the orders agree wherever the margin is larger
    sure = exact.reliability > 2.8e-5
    assert np.count_nonzero(exact.valid & ~sure) <= 2
    np.testing.assert_array_equal(fast.fringe_order[sure], exact.fringe_order[sure])
    assert np.abs(fast.reliability - exact.reliability).max() < 2.8e-5  # measured 1.3e-5
    both = sure & exact.valid
    ulp = np.spacing(np.float32(2 * np.pi * f_h))
    assert np.abs(fast.absolute_phase[both] - exact.absolute_phase[both].astype(np.float32)).max() <= 2 * ulp
    with pytest.raises(ValueError, match="psi_l must be a wrapped phase in"):
        tpu.unwrap_mf_float32(psi_h, psi_l + np.float32(7.0), f_h)


@pytest.mark.parametrize("f_h", HIGH_FREQUENCIES)
def test_unwrap_mw_recovers_orders_with_unit_equivalent_frequency(scene, f_h):
    f_l = f_h - 1
    result = tpu.unwrap_mw(wrapped(scene, f_h), wrapped(scene, f_l), f_h, f_l)
    assert_recovers_scene(result, scene, f_h)


@pytest.mark.parametrize("f_h", HIGH_FREQUENCIES)
def test_unwrap_nt_recovers_orders_for_rational_low_frequency(scene, f_h):
    result = tpu.unwrap_nt(
        wrapped(scene, f_h), wrapped(scene, NT_LOW_FREQUENCY), f_h, NT_LOW_FREQUENCY, EXTENT_PX
    )
    assert_recovers_scene(result, scene, f_h)
    assert result.n_rejected == 0


@pytest.mark.parametrize("method, f_l", [("mf", 1.0), ("mw", 63.0), ("nt", NT_LOW_FREQUENCY)])
def test_unwrap_dispatcher_recovers_orders_by_method_name(scene, method, f_l):
    result = tpu.unwrap(method, wrapped(scene, 64), wrapped(scene, f_l), 64, f_l, extent=EXTENT_PX)
    assert_recovers_scene(result, scene, 64)


def test_convention_order_is_floor_of_phase_over_two_pi_at_period_start():
    # x_p = 0 (first pixel centre) has order 0; just past one period (W/f px) the order is 1.
    x_p = np.array([[0.0, EXTENT_PX / 16 + 1e-3, EXTENT_PX / 16 - 1e-3]])
    result = tpu.unwrap_mf(wrapped(x_p, 16), wrapped(x_p, 1), 16)
    np.testing.assert_array_equal(result.fringe_order, [[0, 1, 0]])


def test_unwrap_with_reference_unwraps_against_absolute_low_phase_above_one(scene):
    f_h, f_l = 64.0, 8.0
    result = tpu.unwrap_with_reference(wrapped(scene, f_h), 2 * np.pi * f_l * scene / EXTENT_PX, f_h, f_l)
    assert_recovers_scene(result, scene, f_h)


# --- noise: MF success rate against the analytic prediction ----------------------------------


@pytest.mark.parametrize("ratio, sigma_rad", [(8, 0.25), (16, 0.15), (32, 0.05), (64, 0.04)])
def test_unwrap_mf_success_rate_matches_erf_prediction(ratio, sigma_rad):
    # Derivation: with f_l = 1 (k_l = 0) the rounded quantity of Eq. (5) is
    #   q = (r*psi_l - psi_h)/(2*pi),  r = f_h/f_l.
    # Noisy phases psi_l = phi_l + d_l (kept unwrapped: x_p in the middle half of the projector,
    # 6*sigma from 0 and 2*pi) and psi_h = phi_h + d_h - 2*pi*k (k = floor((phi_h + d_h)/2*pi), the
    # order that matches the noisy wrapped phase), with r*phi_l = phi_h, give
    #   q = k + (r*d_l - d_h)/(2*pi).
    # The error e = (r*d_l - d_h)/(2*pi) is Gaussian with std s = sigma*sqrt(r^2 + 1)/(2*pi), and
    # the order is right iff |e| < 1/2, so P = erf(1/(2*sqrt(2)*s)) = erf(pi/(sqrt(2)*sigma*sqrt(r^2+1))).
    rng = np.random.default_rng(0)
    shape = (400, 500)  # 200k pixels: binomial std of the rate < 0.1 percentage point
    x_p = rng.uniform(0.25 * EXTENT_PX, 0.75 * EXTENT_PX, shape)
    phi_h = 2 * np.pi * ratio * x_p / EXTENT_PX
    phi_l = 2 * np.pi * x_p / EXTENT_PX
    noisy_h = phi_h + rng.normal(0.0, sigma_rad, shape)
    noisy_l = phi_l + rng.normal(0.0, sigma_rad, shape)
    assert noisy_l.min() > 0 and noisy_l.max() < 2 * np.pi  # the low phase does not wrap
    result = tpu.unwrap_mf(np.mod(noisy_h, 2 * np.pi), noisy_l, ratio, 1.0)
    truth = np.floor(noisy_h / (2 * np.pi)).astype(np.int32)
    rate = np.mean(result.fringe_order == truth)
    predicted = erf(np.pi / (np.sqrt(2) * sigma_rad * np.sqrt(ratio**2 + 1)))
    assert 0.6 < predicted < 0.99
    assert abs(rate - predicted) < 0.01, (rate, predicted)


def test_reliability_is_one_minus_twice_the_rounding_distance():
    # f_h = 8: psi_h = pi and r*psi_l/(2*pi) = 3.75 give q = 3.75 - 0.5 = 3.25 -> k = 3, reliability 0.5.
    psi_h = np.full((1, 1), np.pi)
    psi_l = np.full((1, 1), 2 * np.pi * 3.75 / 8)
    result = tpu.unwrap_mf(psi_h, psi_l, 8)
    assert result.fringe_order[0, 0] == 3
    assert result.reliability[0, 0] == pytest.approx(0.5, abs=1e-12)
    assert result.absolute_phase[0, 0] == pytest.approx(np.pi + 6 * np.pi, abs=1e-12)


# --- heterodyne --------------------------------------------------------------------------------

CFPE_EXTENT_PX = 1920.0
CFPE_PERIODS_PX = (42.0, 45.0, 48.0)


def cfpe_projector_x(shape=(120, 160)):
    rng = np.random.default_rng(0)
    return rng.uniform(0.0, CFPE_EXTENT_PX, shape)


def test_unwrap_heterodyne_recovers_orders_for_cfpe_periods():
    x_p = cfpe_projector_x()
    freqs = [CFPE_EXTENT_PX / p for p in CFPE_PERIODS_PX]
    assert_off_period_boundaries(x_p, freqs, CFPE_EXTENT_PX)
    phases = [wrapped(x_p, f, CFPE_EXTENT_PX) for f in freqs]
    final_beat = (freqs[0] - freqs[1]) - (freqs[1] - freqs[2])
    assert final_beat == pytest.approx(0.381, abs=1e-3)
    result = tpu.unwrap_heterodyne(phases, freqs)
    np.testing.assert_array_equal(result.fringe_order, np.floor(x_p / 42.0).astype(np.int32))
    np.testing.assert_allclose(result.absolute_phase, 2 * np.pi * x_p / 42.0, rtol=0, atol=1e-9)
    assert result.valid.all() and result.reliability.min() > 0.999
    # frequencies in any order: sorted internally, the result is for the highest (42 px)
    shuffled = tpu.unwrap_heterodyne(phases[::-1], freqs[::-1])
    np.testing.assert_array_equal(shuffled.fringe_order, result.fringe_order)


def test_unwrap_heterodyne_handles_ascending_beats(scene):
    # f = 36, 35.5, 34.2: beats 0.5 < 1.3, so the final beat is 1.3 - 0.5 = 0.8 (phase sign flipped)
    freqs = [36.0, 35.5, 34.2]
    assert_off_period_boundaries(scene, freqs)
    result = tpu.unwrap_heterodyne([wrapped(scene, f) for f in freqs], freqs)
    order, phase = expected_order_and_phase(scene, 36.0)
    np.testing.assert_array_equal(result.fringe_order, order)
    np.testing.assert_allclose(result.absolute_phase, phase, rtol=0, atol=1e-9)


def test_unwrap_heterodyne_of_two_frequencies_equals_mw(scene):
    psi_h, psi_l = wrapped(scene, 48), wrapped(scene, 47)
    het = tpu.unwrap_heterodyne([psi_h, psi_l], [48, 47])
    mw = tpu.unwrap_mw(psi_h, psi_l, 48, 47)
    np.testing.assert_array_equal(het.fringe_order, mw.fringe_order)
    np.testing.assert_array_equal(het.fringe_order, np.floor(48 * scene / EXTENT_PX))


def test_unwrap_heterodyne_rejects_final_beat_above_one():
    psi = np.zeros((4, 4))
    # periods 20, 30, 40 px over 1920 px: f = 96, 64, 48; beats 32, 16; final beat 16 > 1
    with pytest.raises(ValueError, match=r"final beat must be in \(0, 1\].*got 16 > 1"):
        tpu.unwrap_heterodyne([psi, psi, psi], [96, 64, 48])


def test_unwrap_heterodyne_rejects_zero_beat_and_wrong_counts():
    psi = np.zeros((4, 4))
    with pytest.raises(ValueError, match="beat is 0"):
        tpu.unwrap_heterodyne([psi, psi, psi], [3, 2, 1])
    with pytest.raises(ValueError, match="2 or more frequencies"):
        tpu.unwrap_heterodyne([psi], [3])
    with pytest.raises(ValueError, match="2 phases and 3 frequencies"):
        tpu.unwrap_heterodyne([psi, psi], [3, 2, 1])


# --- number-theoretic ---------------------------------------------------------------------------


def test_nt_period_pair_is_coprime_with_the_period_ratio():
    p_h, p_l = tpu.nt_period_pair(64, 10.9, EXTENT_PX)
    assert (p_h, p_l) == (109, 640)
    assert math.gcd(p_h, p_l) == 1
    lambda_h, lambda_l = EXTENT_PX / 64, EXTENT_PX / 10.9
    assert p_h / p_l == pytest.approx(lambda_h / lambda_l, rel=1e-12)
    assert math.lcm(p_h, p_l) >= 64 * p_h  # the extent in period units


def test_nt_period_pair_rejects_ambiguous_pair():
    with pytest.raises(ValueError, match=r"ambiguous NT pair.*LCM\(1, 2\) = 2 < extent 20"):
        tpu.nt_period_pair(20, 10, EXTENT_PX)


def test_nt_period_pair_rejects_equal_irrational_and_bad_frequencies():
    with pytest.raises(ValueError, match="different frequencies"):
        tpu.nt_period_pair(16, 16, EXTENT_PX)
    with pytest.raises(ValueError, match="not close to a rational"):
        tpu.nt_period_pair(64, math.pi, EXTENT_PX)
    with pytest.raises(ValueError, match="f_l must be a finite frequency > 0"):
        tpu.nt_period_pair(64, float("nan"), EXTENT_PX)
    with pytest.raises(ValueError, match="f_h must be a finite frequency > 0"):
        tpu.nt_period_pair(0, 10.9, EXTENT_PX)
    with pytest.raises(ValueError, match="extent must be"):
        tpu.nt_period_pair(64, 10.9, -1)


# NT lookup table, noise tolerance and rejection: tests/fpp/test_tpu_nt.py


# --- invalid pixels and masks ----------------------------------------------------------------------


def test_nan_pixels_become_invalid_with_nan_phase_and_zero_order(scene):
    psi_h, psi_l = wrapped(scene, 32), wrapped(scene, 1)
    psi_h[3, 4] = np.nan
    psi_l[10, 20] = np.nan
    result = tpu.unwrap_mf(psi_h, psi_l, 32)
    assert np.count_nonzero(~result.valid) == 2
    assert not result.valid[3, 4] and not result.valid[10, 20]
    assert np.isnan(result.absolute_phase[3, 4]) and result.fringe_order[10, 20] == 0
    assert np.count_nonzero(np.isnan(result.absolute_phase)) == 2


def test_valid_mask_limits_the_unwrapped_pixels(scene):
    psi_h, psi_l = wrapped(scene, 32), wrapped(scene, 31)
    mask = np.ones(scene.shape, dtype=bool)
    mask[:, :10] = False
    psi_h[:, :5] = np.nan  # NaN only where the mask says invalid: allowed
    result = tpu.unwrap_mw(psi_h, psi_l, 32, 31, valid=mask)
    np.testing.assert_array_equal(result.valid, mask)
    order, _ = expected_order_and_phase(scene, 32)
    np.testing.assert_array_equal(result.fringe_order[mask], order[mask])


def test_nan_where_valid_mask_is_true_raises(scene):
    psi_h, psi_l = wrapped(scene, 32), wrapped(scene, 1)
    psi_h[0, 0] = np.nan
    with pytest.raises(ValueError, match="1 pixels are NaN in psi_h, psi_l where valid is True"):
        tpu.unwrap_mf(psi_h, psi_l, 32, valid=np.ones(scene.shape, dtype=bool))


def test_all_nan_input_raises():
    with pytest.raises(ValueError, match="psi_l is all NaN"):
        tpu.unwrap_mf(np.zeros((4, 4)), np.full((4, 4), np.nan), 16)


# --- bad input -----------------------------------------------------------------------------------


def test_mismatched_shapes_raise_with_both_shapes():
    with pytest.raises(ValueError, match=r"same shape; got \(4, 5\) and \(4, 6\)"):
        tpu.unwrap_mf(np.zeros((4, 5)), np.zeros((4, 6)), 16)
    with pytest.raises(ValueError, match=r"valid must be a bool array of shape \(4, 5\)"):
        tpu.unwrap_mf(np.zeros((4, 5)), np.zeros((4, 5)), 16, valid=np.ones((4, 5)))


@pytest.mark.parametrize("f_h", [0.0, -16.0, float("nan"), float("inf")])
def test_bad_high_frequency_raises(f_h):
    psi = np.zeros((4, 4))
    with pytest.raises(ValueError, match="f_h must be a finite frequency > 0"):
        tpu.unwrap_mf(psi, psi, f_h)
    with pytest.raises(ValueError, match="f_h must be a finite frequency > 0"):
        tpu.unwrap_mw(psi, psi, f_h, 15)


def test_mw_with_equivalent_frequency_above_one_raises():
    psi = np.zeros((4, 4))
    with pytest.raises(ValueError, match=r"f_h = 64, f_l = 60, f_eq = 4"):
        tpu.unwrap_mw(psi, psi, 64, 60)
    with pytest.raises(ValueError, match=r"f_eq = -1"):
        tpu.unwrap_mw(psi, psi, 63, 64)


def test_mf_with_low_frequency_above_one_points_to_reference_unwrapping():
    psi = np.zeros((4, 4))
    with pytest.raises(ValueError, match="f_l <= 1.*unwrap_with_reference"):
        tpu.unwrap_mf(psi, psi, 64, 8)


def test_phase_outside_zero_two_pi_raises():
    psi = np.full((4, 4), -1.0)  # an arctan2 phase in (-pi, pi]
    with pytest.raises(ValueError, match=r"psi_h must be a wrapped phase in \[0, 2\*pi\)"):
        tpu.unwrap_mf(psi, np.zeros((4, 4)), 16)
    with pytest.raises(ValueError, match=r"non-empty 2-D array \(H, W\); got shape \(16,\)"):
        tpu.unwrap_mf(np.zeros(16), np.zeros(16), 16)


def test_dispatcher_rejects_unknown_method_and_nt_without_extent():
    psi = np.zeros((4, 4))
    with pytest.raises(ValueError, match="unknown TPU method 'gray'; expected one of mf, mw, nt"):
        tpu.unwrap("gray", psi, psi, 16, 1)
    with pytest.raises(ValueError, match="method 'nt' needs extent"):
        tpu.unwrap("nt", psi, psi, 64, 10.9)


def test_mw_equivalent_phase_is_np_mod_bit_for_bit():
    # The masked two-pass wrap of unwrap_mw gives the numbers np.mod gives for differences of two wrapped
    # phases (tolerance 1e-6 rad included), at the edges and on random values.
    rng = np.random.default_rng(0)
    two_pi = 2 * np.pi
    edges = np.array([0.0, -1e-17, 1e-17, -two_pi + 1e-12, two_pi - 1e-12, two_pi, two_pi + 1e-7,
                      -1e-6 - two_pi + 1e-9, np.pi, -np.pi, np.nextafter(two_pi, 0)])
    difference = np.concatenate([edges, rng.uniform(-two_pi, two_pi, 10000)])
    np.testing.assert_array_equal(tpu._mod_two_pi(difference.copy()), np.mod(difference, two_pi))


def test_inf_in_a_phase_map_raises():
    psi = np.full((4, 5), 1.0)
    psi[1, 2] = np.inf
    with pytest.raises(ValueError, match="psi_l must not contain inf"):
        tpu.unwrap_mf(np.full((4, 5), 1.0), psi, 8.0)
