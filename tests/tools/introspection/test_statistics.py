"""``topic hz`` and ``topic bw`` statistics against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

from dptpu.tools.introspection import BandwidthWindow, RateWindow, format_bandwidth, format_rate


def test_rate_of_evenly_spaced_arrivals_is_exact():
    window = RateWindow(100)
    for i in range(21):
        window.add(10.0 + i * 0.05)  # 20 Hz
    stats = window.statistics()
    assert stats.average_rate_hz == pytest.approx(20.0)
    assert stats.min_s == pytest.approx(0.05) and stats.max_s == pytest.approx(0.05)
    assert stats.std_dev_s == pytest.approx(0.0, abs=1e-12)
    assert stats.window == 21


def test_rate_statistics_equal_numpy_on_jittered_arrivals_and_the_window_keeps_the_last_n():
    rng = np.random.default_rng(0)
    times = np.cumsum(rng.uniform(0.04, 0.06, size=50))
    window = RateWindow(10)
    for t in times:
        window.add(t)
    intervals = np.diff(times[-10:])
    stats = window.statistics()
    assert stats.window == 10 and window.total_count == 50
    assert stats.average_rate_hz == pytest.approx(1.0 / intervals.mean())
    assert (stats.min_s, stats.max_s) == (pytest.approx(intervals.min()), pytest.approx(intervals.max()))
    assert stats.std_dev_s == pytest.approx(intervals.std())  # population std dev, as ros2


def test_rate_needs_two_arrivals_and_a_valid_window():
    window = RateWindow(5)
    assert window.statistics() is None
    window.add(1.0)
    assert window.statistics() is None
    with pytest.raises(ValueError, match="rate window must be an int >= 2 \\(messages\\); got 1"):
        RateWindow(1)


def test_format_rate_is_the_ros2_layout():
    window = RateWindow()
    for t in (0.0, 0.1, 0.3):
        window.add(t)
    assert format_rate(window.statistics()) == ("average rate: 6.667\n\tmin: 0.100s max: 0.200s std dev: 0.05000s "
                                                "window: 3")


def test_bandwidth_is_bytes_since_the_first_message_of_the_window():
    window = BandwidthWindow(3)
    for t, size in ((0.0, 100), (1.0, 200), (2.0, 300), (3.0, 400)):
        window.add(t, size)
    stats = window.statistics(now_s=4.0)  # window: 200, 300, 400 since t = 1.0
    assert stats.bytes_per_s == pytest.approx(900 / 3.0)
    assert (stats.mean_bytes, stats.min_bytes, stats.max_bytes, stats.count) == (300.0, 200, 400, 3)
    assert format_bandwidth(stats) == ("300.00B/s from 3 messages\n"
                                       "\tMessage size mean: 300.00B min: 200.00B max: 400.00B")


def test_bandwidth_units_follow_the_rate():
    window = BandwidthWindow()
    window.add(0.0, 7_372_800)
    text = format_bandwidth(window.statistics(now_s=0.5))
    assert text == "14.75MB/s from 1 messages\n\tMessage size mean: 7.37MB min: 7.37MB max: 7.37MB"


def test_bandwidth_bad_input():
    with pytest.raises(ValueError, match="bandwidth window must be an int >= 1"):
        BandwidthWindow(0)
    with pytest.raises(ValueError, match="message size must be an int >= 0 \\(bytes\\); got -1"):
        BandwidthWindow().add(0.0, -1)
    assert BandwidthWindow().statistics(now_s=1.0) is None
