"""The scan monitor's latency percentiles in fixed memory (issue 19: the monitor kept every scan's latency)."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.nodes.scan_monitor.latency_histogram import LatencyHistogram

RNG = np.random.default_rng(19)
SAMPLES = {
    "lognormal": RNG.lognormal(3.0, 1.0, 20_000),        # a long tail, as the loaded machine's latencies
    "uniform": RNG.uniform(5.0, 500.0, 5_000),
    "bimodal": np.r_[RNG.normal(20.0, 2.0, 9_900), RNG.normal(400.0, 30.0, 100)],  # 1 % stalls: p99 between
    "one": np.array([42.0]),
    "two": np.array([10.0, 1000.0]),
    "three": np.array([100.0, 200.0, 300.0]),
    "constant": np.full(50, 7.0),
    "microseconds": RNG.uniform(0.002, 0.01, 300),
    "hours": RNG.uniform(1e5, 9e6, 300),
}


@pytest.mark.parametrize("name", SAMPLES)
def test_percentiles_match_numpy_within_the_bin_resolution(name):
    values = SAMPLES[name]
    histogram = LatencyHistogram(relative_width=2e-3)
    for value in values:
        histogram.add(value)
    assert len(histogram) == values.size
    for q in (0, 1, 50, 90, 99, 99.9, 100):
        expected = np.percentile(values, q)
        assert histogram.percentile(q) == pytest.approx(expected, rel=1e-3), q  # half the bin width: 1e-3
    assert histogram.percentile(0) == values.min() and histogram.percentile(100) == values.max()  # exact


def test_memory_is_fixed_whatever_the_number_of_scans():
    histogram = LatencyHistogram()
    size = histogram.nbytes
    values = RNG.lognormal(3.0, 0.5, 200_000)
    for value in values:
        histogram.add(value)
    assert histogram.nbytes == size < 100_000  # 8 bytes a scan would be 1.6 MB here
    assert histogram.percentile(99) == pytest.approx(np.percentile(values, 99), rel=1e-3)


def test_values_outside_the_range_count_as_the_extremes_and_bad_input_is_refused():
    histogram = LatencyHistogram(lowest=1.0, highest=1000.0)
    for value in (-5.0, 0.5, 10.0, 5000.0):  # a negative latency: clocks of two hosts apart
        histogram.add(value)
    assert histogram.percentile(0) == -5.0 and histogram.percentile(100) == 5000.0
    assert histogram.percentile(50) == pytest.approx(np.percentile([-5.0, -5.0, 10.0, 5000.0], 50), rel=1e-3)
    with pytest.raises(ValueError, match="finite"):
        histogram.add(float("nan"))
    with pytest.raises(ValueError, match=r"\[0, 100\]"):
        histogram.percentile(101)
    with pytest.raises(ValueError, match="no latency"):
        LatencyHistogram().percentile(50)
