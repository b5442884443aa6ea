"""Percentiles of every scan's latency in fixed memory: a histogram with logarithmic bins.

The scan monitor reports p50 and p99 of the latency over every scan it saw. Keeping each value (8 bytes a scan)
grows without bound on a scanner that runs for weeks; a reservoir sample would make p99 a guess. The histogram
keeps counts in bins whose edges grow by a fixed ratio ``1 + relative_width``, so a value's bin knows it to
``relative_width / 2`` of its size, whatever its magnitude, in a fixed number of counters.
:meth:`LatencyHistogram.percentile` interpolates between order statistics as ``numpy.percentile`` does (its
default, ``linear``), with each order statistic read as its bin's geometric centre (the smallest and largest
value are kept exactly), so it matches ``numpy.percentile`` of the same values to within ``relative_width / 2``.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["LatencyHistogram"]


class LatencyHistogram:
    """Counts of positive values in logarithmic bins, for percentiles in fixed memory.

    Parameters
    ----------
    lowest, highest : float
        The range the bins cover (milliseconds for latencies: 1 us to 2.8 hours by default). A value below
        ``lowest`` (a clock offset between hosts can make a latency negative) counts as the smallest value seen,
        one above ``highest`` as the largest.
    relative_width : float
        Ratio of neighbouring bin edges, minus one: the percentiles' relative resolution is half of it.
    """

    def __init__(self, lowest: float = 1e-3, highest: float = 1e7, relative_width: float = 2e-3):
        if not 0.0 < lowest < highest or not math.isfinite(highest) or not 0.0 < relative_width < 1.0:
            raise ValueError(f"need 0 < lowest < highest < inf and 0 < relative_width < 1; got {lowest}, {highest}, "
                             f"{relative_width}")
        self.lowest = float(lowest)
        self._log_step = math.log1p(relative_width)
        bins = math.ceil(math.log(highest / lowest) / self._log_step)
        self.counts = np.zeros(bins + 2, dtype=np.int64)  # [0]: below lowest, [-1]: above highest
        self.count = 0
        self.minimum = math.inf
        self.maximum = -math.inf

    def __len__(self) -> int:
        return self.count

    @property
    def nbytes(self) -> int:
        """Memory of the counts: fixed at construction."""
        return int(self.counts.nbytes)

    def add(self, value: float) -> None:
        """Count ``value`` (finite)."""
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"a latency must be finite; got {value}")
        if value < self.lowest:
            index = 0
        else:
            index = min(1 + int(math.log(value / self.lowest) / self._log_step), len(self.counts) - 1)
        self.counts[index] += 1
        self.count += 1
        self.minimum = min(self.minimum, value)
        self.maximum = max(self.maximum, value)

    def _order_statistic(self, rank: int, cumulative: np.ndarray) -> float:
        """The ``rank``-th smallest value (0-based) as its bin's geometric centre (exact for the extremes)."""
        if rank <= 0:
            return self.minimum
        if rank >= self.count - 1:
            return self.maximum
        index = int(np.searchsorted(cumulative, rank, side="right"))
        if index == 0:
            return self.minimum
        if index == len(self.counts) - 1:
            return self.maximum
        centre = self.lowest * math.exp((index - 0.5) * self._log_step)
        return min(max(centre, self.minimum), self.maximum)

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile (0-100) as ``numpy.percentile(values, q)`` gives it, to the bins' resolution.

        Raises
        ------
        ValueError
            No value was added, or ``q`` is outside [0, 100].
        """
        if not self.count:
            raise ValueError("no latency counted yet")
        if not 0.0 <= q <= 100.0:
            raise ValueError(f"a percentile is in [0, 100]; got {q}")
        cumulative = np.cumsum(self.counts)
        position = q / 100.0 * (self.count - 1)  # numpy's 'linear': between order statistics floor and ceil
        below = math.floor(position)
        low = self._order_statistic(below, cumulative)
        if position == below:
            return low
        high = self._order_statistic(below + 1, cumulative)
        return low + (position - below) * (high - low)
