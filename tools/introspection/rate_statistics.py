"""Message rate over a sliding window of arrival times (``dptpu topic hz``, as ``ros2 topic hz``).

The statistics are those of ``ros2 topic hz``: over the last ``window`` arrivals, the intervals
``dt_i = t_i - t_{i-1}`` between consecutive messages give

- ``average rate = 1 / mean(dt)`` in Hz,
- ``min``, ``max`` of ``dt`` in seconds,
- ``std dev = sqrt(mean((dt - mean(dt))**2))`` in seconds (population standard deviation),
- ``window``: the number of arrivals the figures use (intervals + 1).

Convention: arrival times are seconds of a monotonic clock (``time.monotonic()``), taken when the
message is handed to the callback.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["RateStatistics", "RateWindow", "format_rate", "DEFAULT_RATE_WINDOW"]

#: Arrivals kept by default (``ros2 topic hz``'s default window).
DEFAULT_RATE_WINDOW = 10000


@dataclass(frozen=True)
class RateStatistics:
    """Rate figures of one window.

    Attributes
    ----------
    average_rate_hz : float
        ``1 / mean(dt)``, Hz.
    min_s, max_s, std_dev_s : float
        Smallest, largest interval and their population standard deviation, seconds.
    window : int
        Arrivals used (>= 2).
    """

    average_rate_hz: float
    min_s: float
    max_s: float
    std_dev_s: float
    window: int

    def to_dict(self) -> dict:
        return {"average_rate_hz": self.average_rate_hz, "min_s": self.min_s, "max_s": self.max_s,
                "std_dev_s": self.std_dev_s, "window": self.window}


class RateWindow:
    """The last ``window`` arrival times of a topic.

    Parameters
    ----------
    window : int
        Arrivals kept, >= 2.

    Raises
    ------
    ValueError
        ``window`` is not an int >= 2.
    """

    def __init__(self, window: int = DEFAULT_RATE_WINDOW):
        if isinstance(window, bool) or not isinstance(window, int) or window < 2:
            raise ValueError(f"rate window must be an int >= 2 (messages); got {window!r}")
        self.window = window
        self._times_s: deque = deque(maxlen=window)
        self.total_count = 0

    def add(self, arrival_s: float) -> None:
        """Record one arrival at ``arrival_s`` seconds (monotonic clock, non-decreasing)."""
        self._times_s.append(float(arrival_s))
        self.total_count += 1

    def __len__(self) -> int:
        return len(self._times_s)

    def statistics(self) -> RateStatistics | None:
        """The figures of the current window, or None with fewer than 2 arrivals or zero elapsed time."""
        if len(self._times_s) < 2:
            return None
        intervals_s = np.diff(np.asarray(self._times_s, dtype=np.float64))  # (n - 1,)
        mean_s = float(intervals_s.mean())
        if mean_s <= 0.0:
            return None
        return RateStatistics(average_rate_hz=1.0 / mean_s, min_s=float(intervals_s.min()),
                              max_s=float(intervals_s.max()), std_dev_s=float(intervals_s.std()),
                              window=len(self._times_s))


def format_rate(stats: RateStatistics) -> str:
    """``ros2 topic hz``'s two lines: ``average rate: 20.001``, then
    ``\\tmin: ...s max: ...s std dev: ...s window: N``."""
    return (f"average rate: {stats.average_rate_hz:.3f}\n"
            f"\tmin: {stats.min_s:.3f}s max: {stats.max_s:.3f}s std dev: {stats.std_dev_s:.5f}s "
            f"window: {stats.window}")
