"""Solid patches one low period apart between two fringe orders (dptpu.fpp.low_period_disputes)."""
import numpy as np
import pytest

from dptpu.fpp.low_period_disputes import low_period_disputes

RATIO = 64.0 / 10.9  # NT 64 / 10.9: one low period moves the high order by 5 or 6


def _orders(shape=(40, 50)):
    reference = np.tile(np.arange(shape[1]) // 4, (shape[0], 1)).astype(np.int32)  # a ramp of orders
    return reference.copy(), reference, np.ones(shape, dtype=bool)


@pytest.mark.parametrize("step", [5, 6, -5, -6])
def test_a_solid_patch_one_low_period_off_is_disputed_whole(step):
    order, reference, valid = _orders()
    order[10:22, 15:27] += step  # 12 x 12
    order[15, 27:29] += step  # a ragged border: two pixels sticking out of the patch
    disputed = low_period_disputes(order, reference, RATIO, valid)
    assert np.array_equal(disputed, order != reference)


def test_speckle_other_steps_small_patches_and_invalid_pixels_are_not_disputed():
    order, reference, valid = _orders()
    rng = np.random.default_rng(3)
    speckle = rng.random(order.shape) < 0.3  # a per-pixel lookup's errors at noise: 30 % of the pixels, at random
    order[speckle] += rng.choice([-6, -5, 5, 6], size=int(speckle.sum()))
    assert not low_period_disputes(order, reference, RATIO, valid).any()
    order, reference, valid = _orders()
    order[5:17, 5:17] += 1  # one HIGH order off: not a low period
    order[25:29, 30:35] += 6  # 20 pixels: below min_pixels
    order[25:37, 5:17] += 6
    valid[25:37, 5:17] = False  # where the reference has no order
    assert not low_period_disputes(order, reference, RATIO, valid).any()
    assert low_period_disputes(order, reference, RATIO, valid, min_pixels=20)[25:29, 30:35].all()


def test_bad_arguments_are_refused():
    order, reference, valid = _orders()
    with pytest.raises(ValueError, match="frequency_ratio"):
        low_period_disputes(order, reference, 1.0, valid)
    with pytest.raises(ValueError, match="one shape"):
        low_period_disputes(order, reference[:, :-1], RATIO, valid)
    with pytest.raises(ValueError, match="min_pixels"):
        low_period_disputes(order, reference, RATIO, valid, min_pixels=0)
