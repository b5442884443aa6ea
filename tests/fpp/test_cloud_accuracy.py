"""Precision and completeness of a published cloud against ground truth (dptpu.fpp.cloud_accuracy), counted exactly."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.cloud_accuracy import cloud_accuracy, order_shift


def _scene(noise_mm: float = 0.1):
    rng = np.random.default_rng(4)
    truth_depth = np.full((10, 20), 600.0)
    truth_depth[:, :2] = np.nan  # no surface: the left two columns
    truly_valid = np.isfinite(truth_depth)
    truly_valid[0, 2:6] = False  # seen but in the projector's shadow
    depth = truth_depth + rng.normal(0.0, noise_mm, truth_depth.shape)
    return truth_depth, truly_valid, depth


def test_wrong_orders_flying_points_and_points_in_the_air_are_counted_once_each():
    truth_depth, truly_valid, depth = _scene()
    published = truly_valid.copy()
    published[5, 10:14] = False  # 4 truly valid pixels not published
    published[3, 0] = True  # a point where there is no surface at all
    depth[3, 0] = 550.0
    shift = np.zeros(depth.shape)
    shift[~truly_valid] = np.nan
    shift[2, 7] = 1  # a wrong order (its depth is wrong too: counted once, as a wrong order)
    depth[2, 7] += 3.0
    depth[6, 8] += 40.0  # a flying point: right order, 40 mm off
    accuracy = cloud_accuracy(published, truly_valid, shift=shift, depth=depth, truth_depth=truth_depth)
    assert (accuracy.published, accuracy.truly_valid) == (int(truly_valid.sum()) - 4 + 1, int(truly_valid.sum()))
    assert (accuracy.wrong_order, accuracy.off_surface, accuracy.wrong) == (1, 2, 3)
    assert accuracy.wrong_share == pytest.approx(3 / accuracy.published)
    assert accuracy.completeness == pytest.approx((truly_valid.sum() - 4) / truly_valid.sum())
    assert accuracy.off_surface_tolerance == 1.0  # 6 sigma of 0.1 mm noise is under the 1 mm floor


def test_the_tolerance_follows_the_scans_own_noise_above_the_floor():
    truth_depth, truly_valid, depth = _scene(noise_mm=0.5)
    accuracy = cloud_accuracy(truly_valid, truly_valid, depth=depth, truth_depth=truth_depth)
    assert accuracy.off_surface_tolerance == pytest.approx(6 * 0.5, rel=0.2)  # 6 sigma from the MAD of 180 pixels
    assert accuracy.off_surface == 0 and accuracy.wrong_order == 0  # no shift given: orders not judged


def test_order_shift_rounds_the_phase_difference_to_whole_fringes():
    truth = np.array([[1.0, 10.0, np.nan]])
    shift = order_shift(truth + np.array([[0.3, 2 * np.pi - 0.2, 0.0]]), truth)
    assert shift[0, 0] == 0 and shift[0, 1] == 1 and np.isnan(shift[0, 2])


def test_bad_arguments_are_refused_with_what_is_wrong():
    mask = np.ones((3, 4), bool)
    with pytest.raises(ValueError, match=r"share one \(H, W\) shape"):
        cloud_accuracy(mask, np.ones((3, 5), bool))
    with pytest.raises(ValueError, match="depth and truth_depth come together"):
        cloud_accuracy(mask, mask, depth=np.zeros((3, 4)))
    empty = cloud_accuracy(~mask, ~mask)
    assert np.isnan(empty.wrong_share) and np.isnan(empty.completeness)
