"""The figures the scan monitor prints: fringe-order accuracy and depth error against ground truth."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.nodes.scan_monitor.scan_metrics import scan_metrics, trust_verdict


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


def test_metrics_give_the_precision_and_completeness_the_verdict_reads():
    truth_phase = np.tile(np.linspace(0.5, 2 * np.pi * 8, 10), (5, 1))
    truth_depth = np.full((5, 10), 0.8)
    truth_valid = np.ones((5, 10), bool)
    truth_valid[0, :] = False  # 40 truly valid pixels
    phase = truth_phase.copy()
    phase[2, 3] += 2 * np.pi  # one wrong order
    depth = truth_depth.copy()
    depth[2, 3] += 0.004
    depth[3, 5] += 0.0025  # right order, 2.5 mm off: off the surface
    depth[4, :] = np.nan  # 10 truly valid pixels not published
    m = scan_metrics(depth, phase, np.ones((5, 10), bool), truth_phase, truth_valid, truth_depth)
    assert (m.valid_points, m.truly_valid_pixels, m.published_truly_valid) == (40, 40, 30)
    assert (m.wrong_order_points, m.off_surface_points, m.wrong_points) == (1, 1, 2)
    assert m.wrong_share == pytest.approx(2 / 40) and m.completeness == pytest.approx(30 / 40)
    assert trust_verdict(m.wrong_share, m.completeness) == "5.00 % of the points wrong (> 0.10 %)"
    assert trust_verdict(m.wrong_share, m.completeness, max_wrong_share=0.06, min_completeness=0.8) \
        == "completeness 75.0 % (< 80.0 %)"
    assert trust_verdict(0.0005, 0.97) == ""
    assert trust_verdict(float("nan"), float("nan")) == "no point published"


def test_as_dict_is_asdict_and_leaves_the_allocated_blocks_flat():
    """``dataclasses.asdict`` builds a tuple of the fields from a generator on every call; CPython's tuple free list
    kept each one (2,000, 350 KB, over the first scans of a soak; issue 19)."""
    import dataclasses
    import gc
    import sys

    from dptpu.nodes.scan_monitor.scan_metrics import ScanMetrics

    names = [item.name for item in dataclasses.fields(ScanMetrics)]
    metrics = ScanMetrics(**{name: float(index) for index, name in enumerate(names)})
    assert metrics.as_dict() == dataclasses.asdict(metrics)
    gc.collect()
    gc.disable()
    try:
        before = sys.getallocatedblocks()
        for _ in range(3000):
            record = metrics.as_dict()
        del record
        grown = sys.getallocatedblocks() - before
    finally:
        gc.enable()
    assert grown < 100, grown
