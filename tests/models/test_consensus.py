"""Neighbour consensus post-processing of a fringe order (dptpu.models.consensus), on analytic scenes.

The scene: a tilted phase ramp of 6-px fringes (u = x / 6 + y / 20 periods) with a depth step of 3.3
periods at x = 40 (two surfaces), 60x80 pixels; orders and wrapped phases are exact, and the tests damage
the orders the way the network and the classical methods do.
"""
import numpy as np
import pytest

from dptpu.models.consensus import (
    DEFAULT_RADII,
    WIDE_RADII,
    break_share,
    consensus_order,
    phase_gradient,
    prefer_consistent_classical,
    vote_orders,
)

HEIGHT, WIDTH, STEP_X = 60, 80, 40


def _scene():
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    periods = x / 6.0 + y / 20.0 + np.where(x >= STEP_X, 3.3, 0.0)  # absolute phase u, periods
    order = np.floor(periods).astype(np.int32)
    wrapped = 2.0 * np.pi * (periods - order)  # psi_h, radians in [0, 2pi)
    valid = np.ones(order.shape, bool)
    valid[:, :4] = False  # an invalid band (a shadow)
    return order, wrapped, valid


def _isolated_errors(order, fraction, seed):
    """Orders off by +-1 on a random ``fraction`` of the pixels, no two of them 8-neighbours."""
    rng = np.random.default_rng(seed)
    damaged = order.copy()
    taken = np.zeros(order.shape, bool)
    for index in rng.permutation(order.size)[:int(fraction * order.size)]:
        r, c = divmod(int(index), order.shape[1])
        if not taken[max(r - 1, 0):r + 2, max(c - 1, 0):c + 2].any():
            taken[r, c] = True
            damaged[r, c] += rng.choice([-1, 1])
    return damaged, taken


def test_phase_gradient_is_the_ramp_slope_away_from_the_step():
    _, wrapped, valid = _scene()
    gy, gx = phase_gradient(wrapped, valid)
    inside = np.s_[3:-3, 7:STEP_X - 3]  # away from borders, the invalid band and the step
    assert np.allclose(gx[inside], 1.0 / 6.0, atol=1e-5) and np.allclose(gy[inside], 1.0 / 20.0, atol=1e-5)


def test_vote_fixes_every_isolated_wrong_order_and_keeps_the_depth_step():
    order, wrapped, valid = _scene()
    damaged, wrong = _isolated_errors(order, 0.15, seed=1)
    assert wrong[valid].sum() > 200
    damaged[~valid] = 99  # invalid garbage: returned unchanged, never votes
    voted = vote_orders(damaged, wrapped, valid)
    assert np.array_equal(voted[valid], order[valid])
    assert np.all(voted[~valid] == 99)


def test_prefer_consistent_classical_keeps_a_right_classical_strip_and_not_isolated_errors():
    order, wrapped, valid = _scene()
    network = order.copy()
    network[:, STEP_X - 2:STEP_X] += 1  # the network's failure: a 2-px strip off by one along the edge
    classical, wrong = _isolated_errors(order, 0.05, seed=2)  # classical: isolated noise errors
    network[wrong] = order[wrong]  # ... which the network fixed
    merged = prefer_consistent_classical(network, classical, wrapped, valid)
    strip = np.zeros(order.shape, bool)
    strip[:, STEP_X - 2:STEP_X] = True
    # the strip takes the classical order where 5 of its 8 neighbours agree with it: all 5 same-surface
    # neighbours are needed at the edge, so a classical error next to a strip pixel keeps the network's there
    share = np.mean(merged[strip & ~wrong] == order[strip & ~wrong])
    assert share > 0.85  # measured 0.8957
    assert np.array_equal(merged[wrong & ~strip], order[wrong & ~strip])  # isolated classical errors stay fixed


def test_consensus_removes_a_wrong_strip_along_the_depth_edge():
    order, wrapped, valid = _scene()
    network = order.copy()
    network[:, STEP_X - 3:STEP_X] += 1  # a 3-px strip, every pixel off by one
    classical, _ = _isolated_errors(order, 0.15, seed=3)
    before = np.mean(network[valid] == order[valid])
    after = consensus_order(network, classical, wrapped, valid)
    assert before < 0.97
    assert np.array_equal(after[valid], order[valid])


def test_vote_fixes_orders_off_by_several_periods():
    order, wrapped, valid = _scene()
    damaged = order.copy()
    damaged[10:12, 20:22] += 5  # a 2x2 blob off by 5 periods
    damaged[30, 50] -= 17
    damaged[45:48, STEP_X - 2:STEP_X] -= 3  # at the depth edge
    voted = vote_orders(damaged, wrapped, valid)
    assert np.array_equal(voted[valid], order[valid])


def test_break_share_counts_the_pairs_that_wrong_orders_break():
    order, wrapped, valid = _scene()
    pairs = (valid[1:] & valid[:-1]).sum() + (valid[:, 1:] & valid[:, :-1]).sum()
    edge_pairs = HEIGHT  # the depth step breaks one horizontal pair a row
    assert break_share(order, wrapped, valid) == pytest.approx(edge_pairs / pairs)
    damaged, wrong = _isolated_errors(order, 0.15, seed=4)
    isolated = wrong & valid
    isolated[:, STEP_X - 1:STEP_X + 1] = False  # next to the step an error may mend the step's pair
    assert break_share(damaged, wrapped, valid) > 3.5 * isolated.sum() / pairs  # each breaks its 3-4 pairs


def test_consensus_widens_its_windows_for_a_noisy_classical_order():
    order, wrapped, valid = _scene()
    rng = np.random.default_rng(5)
    noisy = order + rng.choice([-1, 0, 0, 1], size=order.shape)  # half the pixels wrong: most pairs broken
    assert break_share(noisy, wrapped, valid) > 0.5
    wide = consensus_order(noisy, noisy, wrapped, valid, radii=WIDE_RADII)
    narrow = consensus_order(noisy, noisy, wrapped, valid, radii=DEFAULT_RADII)
    assert np.mean(wide[valid] == order[valid]) > np.mean(narrow[valid] == order[valid])
    assert np.array_equal(consensus_order(noisy, noisy, wrapped, valid), wide)
    quiet, _ = _isolated_errors(order, 0.05, seed=6)
    assert np.array_equal(consensus_order(quiet, quiet, wrapped, valid),
                          consensus_order(quiet, quiet, wrapped, valid, radii=DEFAULT_RADII))


def test_bad_shapes_name_the_field():
    order, wrapped, valid = _scene()
    with pytest.raises(ValueError, match="classical_order must be a"):
        consensus_order(order, order[:, :-1], wrapped, valid)
    with pytest.raises(ValueError, match="radii >= 1"):
        vote_orders(order, wrapped, valid, radii=(0,))
