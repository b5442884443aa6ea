"""dptpu.models.nt_prior: NT's low order by band consensus and its MF representation for the network.

Analytic checks (a plane seen by the camera, projector columns known exactly) and the analytic step scenes of
:mod:`dptpu.models.toy_dataset` at the nearly degenerate pair f_h = 60 / f_l = 10.9 (``k_l`` and ``k_l + 2``
predict high phases 0.009 periods apart), 2 sigma; a band over a depth edge at 88 / 10.9 and noiseless captures
of outside rigs (:mod:`tests.outside_rigs`), issue 16.
"""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp import tpu
from dptpu.models.inference import FringeOrderModel, shipped_model_path
from dptpu.models.nt_prior import (
    MERGE_TOLERANCE_RAD,
    low_order_bands,
    low_order_from_high,
    merge_tolerance_rad,
    mf_representation,
)
from dptpu.models.refine import refine_order
from dptpu.models.toy_dataset import toy_sample
from dptpu.sim import outside_rigs

TWO_PI = 2.0 * np.pi
EXTENT_PX = 912.0
F_L = 10.9


def _plane(f_h, shape=(60, 160), noise_rad=0.0, seed=0):
    """A plane whose projector column runs 40..880 px across the image: wrapped phases, labels, both orders."""
    rng = np.random.default_rng(seed)
    x_p = np.broadcast_to(np.linspace(40.0, 880.0, shape[1]), shape)  # (H, W) projector px
    phases = []
    for f in (f_h, F_L):
        absolute = TWO_PI * f * x_p / EXTENT_PX
        phases.append(np.mod(absolute + noise_rad * rng.standard_normal(shape), TWO_PI))
    k_h = np.floor(f_h * x_p / EXTENT_PX).astype(np.int32)
    k_l = np.floor(F_L * x_p / EXTENT_PX).astype(np.int32)
    return phases[0], phases[1], k_h, k_l


@pytest.mark.parametrize("f_h", [40.0, 60.0, 96.0])
def test_low_order_from_high_gives_each_lookup_pair(f_h):
    table = tpu.nt_lookup_table(f_h, F_L, EXTENT_PX)
    # one projector column inside every segment of the table: half way between the pair's start and the next break
    start = np.maximum(table.k_h * table.lambda_h_px, table.k_l * table.lambda_l_px)
    end = np.minimum((table.k_h + 1) * table.lambda_h_px, (table.k_l + 1) * table.lambda_l_px)
    x_p = 0.5 * (start + end)[None, :]  # (1, M)
    psi_h = np.mod(TWO_PI * x_p / table.lambda_h_px, TWO_PI)
    psi_l = np.mod(TWO_PI * x_p / table.lambda_l_px, TWO_PI)
    np.testing.assert_array_equal(low_order_from_high(table.k_h[None, :], psi_h, psi_l, f_h, F_L), table.k_l[None, :])


def test_band_order_recovers_the_low_order_where_every_pixel_is_the_degenerate_neighbour():
    psi_h, psi_l, _, k_l = _plane(60.0, noise_rad=0.03, seed=1)
    valid = np.ones(psi_h.shape, bool)
    wrong = k_l + 2  # 60 / 10.9 = 5.5046: k_l + 2 predicts a high phase 0.009 periods away
    order, banded = low_order_bands(psi_h, psi_l, 60.0, F_L, valid, wrong)
    assert banded.mean() > 0.8  # all but the two pixel columns at each of the ~9 wraps
    np.testing.assert_array_equal(order[banded], k_l[banded])
    np.testing.assert_array_equal(order[~banded], wrong[~banded])


def test_a_depth_edge_that_breaks_the_low_phase_splits_the_bands():
    psi_h, psi_l, _, k_l = _plane(60.0, noise_rad=0.02, seed=2)
    psi_h2, psi_l2, _, k_l2 = _plane(60.0, noise_rad=0.02, seed=3)
    shift = 37  # the lower half sees the projector 37 image columns (~194 px, 2.3 low periods) further on
    rows = slice(30, None)
    psi_h[rows, :-shift], psi_l[rows, :-shift], k_l[rows, :-shift] = (psi_h2[rows, shift:], psi_l2[rows, shift:],
                                                                      k_l2[rows, shift:])
    valid = np.ones(psi_h.shape, bool)
    valid[rows, -shift:] = False
    order, banded = low_order_bands(psi_h, psi_l, 60.0, F_L, valid, k_l + 2)
    assert banded.mean() > 0.7
    np.testing.assert_array_equal(order[banded], k_l[banded])


def test_mf_representation_is_the_f1_phase_and_the_mf_order():
    psi_h, psi_l, k_h, k_l = _plane(96.0, noise_rad=0.0)
    valid = np.ones(psi_h.shape, bool)
    nt = mf_representation(psi_h, psi_l, k_h, 96.0, F_L, valid)
    np.testing.assert_array_equal(nt.order_low, k_l)
    np.testing.assert_array_equal(nt.coarse_order, k_h)
    x_p = np.linspace(40.0, 880.0, psi_h.shape[1])
    np.testing.assert_allclose(nt.wrapped_low[0], TWO_PI * x_p / EXTENT_PX, atol=1e-9)  # Psi at one period


def test_mf_representation_fixes_nt_at_a_degenerate_pair_on_analytic_step_scenes():
    classical, prior = [], []
    for seed in range(1, 9):
        sample = toy_sample("nt", 60.0, shape=(120, 160), noise_sigma=3.1386, scene_seed=seed)
        valid, label = sample["valid"], sample["label_order"]
        nt = mf_representation(sample["wrapped_high"], sample["wrapped_low"], sample["coarse_order"], 60.0,
                               float(sample["frequency_low"]), valid)
        classical.append(np.mean(sample["coarse_order"][valid] == label[valid]))
        prior.append(np.mean(nt.coarse_order[valid] == label[valid]))
    # measured, seeds 1-8: classical 26.0 11.7 5.9 10.1 13.7 12.7 29.1 47.4 %; the MF order of the band prior
    # 98.6 98.9 99.7 99.8 98.3 99.3 96.7 99.7 %
    assert np.mean(classical) < 0.3
    assert np.mean(prior) > 0.98 and min(prior) > 0.95


def test_bad_input_names_the_problem():
    psi = np.zeros((4, 5))
    with pytest.raises(ValueError, match=r"shapes \[\(4, 5\), \(4, 4\)"):
        mf_representation(psi, np.zeros((4, 4)), psi, 60.0, F_L, np.ones((4, 5), bool))
    with pytest.raises(ValueError, match="f_h > f_l > 0"):
        mf_representation(psi, psi, psi, 8.0, F_L, np.ones((4, 5), bool))


# --------------------------------------------------------------------------------------------
# Outside rigs (issue 16): a band that runs over a depth edge of one low period at f_h / f_l near 8
# --------------------------------------------------------------------------------------------


def test_merge_tolerance_is_half_the_turn_between_neighbouring_low_orders():
    # 88 / 10.9 = 8.0734: m and m + 1 give residuals 0.0734 periods apart; half of it in radians
    assert merge_tolerance_rad(88.0 / F_L, 11) == pytest.approx(np.pi * (88.0 / F_L - 8.0), rel=1e-12)
    assert merge_tolerance_rad(96.0 / F_L, 11) == pytest.approx(np.pi * (9.0 - 96.0 / F_L), rel=1e-12)  # 0.193
    assert merge_tolerance_rad(60.0 / F_L, 11) == MERGE_TOLERANCE_RAD  # 0.495 periods apart: the cap
    # 0.028 periods apart (half-turn 0.086 rad): below what the window's mean resolves at 2 sigma: the cap
    assert merge_tolerance_rad(76.0 / F_L, 11) == MERGE_TOLERANCE_RAD
    assert merge_tolerance_rad(16.0, 1) == MERGE_TOLERANCE_RAD  # one low order: nothing to confuse


def test_a_depth_edge_that_carries_the_low_phase_on_by_one_period_splits_the_band_at_f88():
    # The right 60 columns see the projector one low period (83.7 px) further on than the left 100 continue:
    # the low phase runs on without a wrap or a jump, the high residual turns by 0.0734 periods (0.46 rad).
    # With the 0.3 pi tolerance of a 3x3 mean this stayed one band and the right side took k_l = 5: 8 orders off.
    f_h, lambda_l = 88.0, EXTENT_PX / F_L
    rng = np.random.default_rng(4)
    columns = np.arange(160)
    x_p = np.broadcast_to(np.linspace(5.05, 5.95, 160) * lambda_l + lambda_l * (columns >= 100), (60, 160))
    psi_h, psi_l = (np.mod(TWO_PI * f * x_p / EXTENT_PX + 0.04 * rng.standard_normal(x_p.shape), TWO_PI)
                    for f in (f_h, F_L))
    k_l = np.floor(F_L * x_p / EXTENT_PX).astype(np.int32)
    valid = np.ones(x_p.shape, bool)
    order, banded = low_order_bands(psi_h, psi_l, f_h, F_L, valid, np.zeros_like(k_l))
    for side in (columns < 100, columns >= 100):
        pixels = banded & side[None, :]
        assert pixels.sum() > 0.9 * 60 * side.sum()
        assert np.mean(order[pixels] == k_l[pixels]) > 0.98  # measured 99.99 % (left), 98.8 % (right)
        away = pixels & (np.abs(columns - 99.5) > 2)[None, :]  # off the edge's columns (the 5x5 window's reach)
        assert np.all(order[away] == k_l[away])


@pytest.mark.parametrize("rig_seed", [None, 1])
def test_band_prior_is_right_on_noiseless_outside_captures_at_f88(rig_seed):
    # issue 16: 12 noiseless steps, 88 / 10.9, two spheres before a tilted plane, mixed pixels (3x3 supersampled),
    # 320x240. Measured: the prior's low order right on 99.88 % (issue 16's rig) and 99.73 % (random rig 1) of the
    # pixels, its MF order on 99.83 / 99.62 % (classical NT 99.78 / 99.79 %); 97.8 / 97.3 % when a 3x3 mean was held
    # to 0.3 pi: a band over a depth edge, 8 orders off
    size = (320, 240)
    rig = outside_rigs.issue16_rig(size) if rig_seed is None else outside_rigs.random_outside_rig(rig_seed, size)
    capture = outside_rigs.render_phases(rig, outside_rigs.spheres_and_plane(rig), [88.0, F_L], steps=12)
    psi_h, psi_l = capture.phases[88.0], capture.phases[F_L]
    valid = capture.valid & (capture.modulation[88.0] > 5.1) & (capture.modulation[F_L] > 5.1)
    classical = tpu.unwrap_nt(psi_h, psi_l, 88.0, F_L, capture.extent, valid=valid)
    nt = mf_representation(psi_h, psi_l, np.where(classical.valid, classical.fringe_order, np.nan), 88.0, F_L,
                           valid)
    assert np.mean(nt.order_low[valid] == capture.order(F_L)[valid]) > 0.995
    assert np.mean(nt.coarse_order[valid] == capture.order(88.0)[valid]) > 0.99


@pytest.mark.skipif(shipped_model_path() is None, reason="no shipped model models/dptpu.onnx")
@pytest.mark.parametrize("rig_seed", [None, 0])
def test_dptpu_nt_reaches_97_percent_on_outside_rigs_at_three_steps_two_sigma(rig_seed):
    # issue 16's goal: DP-TPU NT at 3-step, 2 sigma (3.1386 DN), >= 97 % on rigs outside the training distribution.
    # Measured (160x120, 88 / 96): issue 16's rig 99.46 / 98.41 %, random rig 0 98.85 / 98.77 %; classical NT
    # 35-42 %. docs/model-eval.md "Outside rigs (issue 16)" has the 320x240 table (scripts/nt_outside_rigs.py).
    model = FringeOrderModel.load(shipped_model_path(), threads=1)
    size = (160, 120)
    rig = outside_rigs.issue16_rig(size) if rig_seed is None else outside_rigs.random_outside_rig(rig_seed, size)
    capture = outside_rigs.render_phases(rig, outside_rigs.spheres_and_plane(rig), [88.0, 96.0, F_L], steps=3,
                                         noise_dn=outside_rigs.SIGMA_2)
    for f_h in (88.0, 96.0):
        psi_h, psi_l = capture.phases[f_h], capture.phases[F_L]
        valid = capture.valid & (capture.modulation[f_h] > 5.1) & (capture.modulation[F_L] > 5.1)
        classical = tpu.unwrap_nt(psi_h, psi_l, f_h, F_L, capture.extent, valid=valid)
        order = refine_order(model, "nt", psi_h, psi_l, classical.fringe_order, f_h, F_L, valid,
                             classical_valid=classical.valid)
        truth = capture.order(f_h)
        assert np.mean(classical.fringe_order[valid] == truth[valid]) < 0.5
        assert np.mean(order[valid] == truth[valid]) > 0.97
