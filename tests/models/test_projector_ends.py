"""dptpu.models.projector_ends: Eqs. (5) and (7) at the projector's two ends, on analytic ramps.

A camera row that sees the projector from its first column (order 0) to column 60 of 912 and, in the other
half of the image, from column 852 to its last (order f_h - 1): the phase that spans the projector is near
0 at one end and near 2pi at the other, and noise moves pixels across.
"""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp import tpu
from dptpu.models.projector_ends import coarse_order_at_ends

TWO_PI = 2.0 * np.pi
EXTENT_PX = 912.0


def _ends(f_h, f_l, noise_rad, seed=0, shape=(40, 120)):
    """Wrapped phases of both ends of the projector, side by side, and the true order of f_h."""
    rng = np.random.default_rng(seed)
    half = shape[1] // 2
    x_p = np.concatenate([np.linspace(0.5, 60.0, half), np.linspace(852.0, 911.5, shape[1] - half)])
    x_p = np.broadcast_to(x_p, shape)
    psi = [np.mod(TWO_PI * f * x_p / EXTENT_PX + noise_rad * rng.standard_normal(shape), TWO_PI) for f in (f_h, f_l)]
    return psi[0], psi[1], np.floor(f_h * x_p / EXTENT_PX).astype(np.int32)


@pytest.mark.parametrize(("method", "f_l"), [("mf", 1.0), ("mw", 79.0)])
def test_orders_at_both_ends_of_the_projector_stay_there(method, f_l):
    psi_h, psi_l, truth = _ends(80.0, f_l, noise_rad=0.03)
    valid = np.ones(truth.shape, bool)
    valid[:, 57:63] = False  # a shadow between the two ends
    classical = tpu.unwrap(method, psi_h, psi_l, 80.0, f_l, valid=valid).fringe_order
    ends = coarse_order_at_ends(method, psi_h, psi_l, 80.0, f_l, valid)
    flipped = [int(((np.abs(order - truth) > 40) & valid).sum()) for order in (classical, ends)]
    # read at the other end of the projector, measured (seeds 0-2): MF 143 / 143 / 129 -> 10 / 25 / 6 pixels of
    # 4,560, MW 189 / 194 / 203 -> 18 / 23 / 27 (what is left: the first 3 columns, whose local mean is within
    # its noise of 0)
    assert flipped[0] > 100 and flipped[1] < flipped[0] / 4
    assert np.mean(ends[valid] == truth[valid]) > np.mean(classical[valid] == truth[valid]) + 0.01
    patched = coarse_order_at_ends(method, psi_h, psi_l, 80.0, f_l, valid, classical_order=classical)
    assert np.mean(patched[valid] == ends[valid]) > 0.999  # only the pixels near the ends computed again


def test_away_from_the_ends_it_is_eq_7():
    rng = np.random.default_rng(1)
    x_p = np.broadcast_to(np.linspace(200.0, 700.0, 100), (30, 100))
    psi_h, psi_l = (np.mod(TWO_PI * f * x_p / EXTENT_PX + 0.02 * rng.standard_normal(x_p.shape), TWO_PI)
                    for f in (64.0, 63.0))
    valid = np.ones(x_p.shape, bool)
    valid[:, :10] = False
    ends = coarse_order_at_ends("mw", psi_h, psi_l, 64.0, 63.0, valid)
    classical = tpu.unwrap_mw(psi_h, psi_l, 64.0, 63.0).fringe_order
    np.testing.assert_array_equal(ends[valid], classical[valid])
    assert not ends[~valid].any()


def test_bad_methods_and_frequencies_are_named():
    psi = np.zeros((3, 4))
    valid = np.ones((3, 4), bool)
    with pytest.raises(ValueError, match="'mf' or 'mw'"):
        coarse_order_at_ends("nt", psi, psi, 64.0, 10.9, valid)
    with pytest.raises(ValueError, match="0 < f_h - f_l <= 1"):
        coarse_order_at_ends("mw", psi, psi, 64.0, 60.0, valid)
    with pytest.raises(ValueError, match="f_l <= 1"):
        coarse_order_at_ends("mf", psi, psi, 64.0, 2.0, valid)
