"""The figures the scan monitor prints: fringe-order accuracy and depth error against ground truth."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.nodes.scan_monitor.scan_metrics import scan_metrics


def test_metrics_count_wrong_fringes_and_depth_errors_exactly():
    rng = np.random.default_rng(0)
    truth_phase = rng.uniform(0, 2 * np.pi * 16, (6, 8)).astype(np.float32)
    truth_depth = np.full((6, 8), 0.8)  # float64: 1 mm is exact to 1e-12 here
    truth_valid = np.ones((6, 8), bool)
    truth_valid[0, 0] = False
    phase = truth_phase + 0.01
    phase[1, 1] += 2 * np.pi  # one wrong fringe order (Eq. 3)
    phase[2, 2] -= 4 * np.pi  # another
    phase[3, 3] += 2.0  # wrong phase but the right fringe (|error| < pi)
    depth = truth_depth + 0.001  # 1 mm everywhere
    depth[1, 1] += 0.009  # 10 mm at a wrong order
    depth[5, 7] = np.nan  # no point
    m = scan_metrics(depth, phase, np.ones((6, 8), bool), truth_phase, truth_valid, truth_depth)
    assert (m.valid_points, m.total_pixels, m.compared_pixels, m.order_errors) == (47, 48, 47, 2)
    assert m.order_accuracy == pytest.approx(45 / 47)
    assert m.depth_pixels == 46  # finite points where the truth holds
    assert m.depth_rms_mm == pytest.approx(np.sqrt((45 * 1.0 + 100.0) / 46), rel=1e-5)
    assert m.depth_rms_right_order_mm == pytest.approx(1.0, rel=1e-5)
    assert m.depth_max_abs_mm == pytest.approx(10.0, rel=1e-5)


def test_metrics_refuse_arrays_of_different_shapes():
    a = np.zeros((4, 4))
    with pytest.raises(ValueError, match=r"share one \(H, W\) shape"):
        scan_metrics(a, a, a > 0, np.zeros((4, 5)), a > 0, a)
