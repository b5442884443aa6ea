"""Neighbour support of a fringe order (dptpu.fpp.order_support) and the network confidence that uses it."""
import numpy as np
import pytest

from dptpu.fpp.confidence import network_confidence
from dptpu.fpp.order_support import neighbour_support, phase_gradient

TWO_PI = 2.0 * np.pi


def _tilted_plane(shape=(40, 50), period_px=(6.5, 23.0)):
    """Absolute phase of a plane, periods: fringes of 6.5 px along x, a slow drift along y; (order, wrapped)."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    absolute = 3.2 + cols / period_px[0] + rows / period_px[1]
    order = np.floor(absolute).astype(np.int32)
    return order, TWO_PI * (absolute - order)


def test_phase_gradient_is_the_plane_slope():
    order, wrapped = _tilted_plane()
    gy, gx = phase_gradient(wrapped, np.ones(wrapped.shape, bool))
    assert np.allclose(gy, 1 / 23.0, atol=1e-5) and np.allclose(gx, 1 / 6.5, atol=1e-5)


def test_a_right_order_among_confident_neighbours_is_fully_supported():
    order, wrapped = _tilted_plane()
    valid = np.ones(order.shape, bool)
    support = neighbour_support(order, wrapped, valid, np.ones(order.shape), radius=3)
    assert np.allclose(support, 1.0)
    # neighbours count with their own confidence: all at 0.6 -> 0.6
    assert np.allclose(neighbour_support(order, wrapped, valid, np.full(order.shape, 0.6), radius=3), 0.6)


def test_a_patch_one_order_off_is_supported_by_itself_only():
    order, wrapped = _tilted_plane()
    valid = np.ones(order.shape, bool)
    shifted = order.copy()
    shifted[18:21, 20:23] += 1  # a 3 x 3 patch one order off
    support = neighbour_support(shifted, wrapped, valid, np.ones(order.shape), radius=3)
    assert support[19, 21] == pytest.approx(8 / 48)  # its 8 patch neighbours of 48
    ring = np.zeros(order.shape, bool)
    ring[15:24, 17:26] = True
    ring[18:21, 20:23] = False
    # pixels around it lose only the patch's 9 (or fewer) of their 48
    assert support[ring].min() >= 1 - 9 / 48 - 1e-6


def test_at_a_depth_step_a_pixel_is_supported_by_its_own_side():
    order, wrapped = _tilted_plane((30, 40))
    absolute = order + wrapped / TWO_PI
    absolute[:, 20:] += 2.37  # the right half is another surface, 2.37 periods further
    order2 = np.floor(absolute).astype(np.int32)
    wrapped2 = TWO_PI * (absolute - order2)
    support = neighbour_support(order2, wrapped2, np.ones(order2.shape, bool), np.ones(order2.shape), radius=3)
    # 7 x 7 window at the last column of the left side: at most its own 4 columns, (4*7 - 1) / 48, agree (fewer: the
    # local gradient there averages the step's wrapped difference in): no support at the default threshold
    assert support[15, 19] <= 27 / 48 + 1e-6 and 2 * support[15, 19] - 1 < 0.2
    assert support[15, 16] == pytest.approx(1.0)  # window and gradient window on its own side


def test_invalid_pixels_and_bad_arguments():
    order, wrapped = _tilted_plane((12, 12))
    valid = np.ones(order.shape, bool)
    valid[5, 5] = False
    support = neighbour_support(order, wrapped, valid, np.ones(order.shape), radius=2)
    assert support[5, 5] == 0 and np.allclose(support[valid], 1.0)  # an invalid neighbour neither agrees nor counts
    with pytest.raises(ValueError, match="radius"):
        neighbour_support(order, wrapped, valid, np.ones(order.shape), radius=0)


def test_network_confidence_takes_the_neighbours_support_where_its_own_and_its_prior_fail():
    order, wrapped = _tilted_plane()
    valid = np.ones(order.shape, bool)
    continuous = order.astype(np.float64)
    continuous[10, 10] += 0.9  # the network's own margin there: 1 - 1.8 -> 0
    prior = order.copy()
    prior[10, 10] += 3  # the prior three orders off there
    made_up = order.copy()
    made_up[25:28, 30:33] += 1  # a patch the vote made up: the network and the prior say otherwise
    continuous_patch = order.astype(np.float64)  # the network said the right order there, one below
    patch_prior = order.copy()
    patch_prior[25:28, 30:33] -= 2  # and its prior three below
    without = network_confidence(continuous, order, prior, valid)
    assert without[10, 10] == 0.0
    with_support = network_confidence(continuous, order, prior, valid, wrapped_high=wrapped)
    assert with_support[10, 10] == pytest.approx(1.0)  # every neighbour confidently agrees
    patch = network_confidence(continuous_patch, made_up, patch_prior, valid, wrapped_high=wrapped)
    assert patch[26, 31] == 0.0  # its own margin, its prior and its window (8 of 80 agree) all fail
