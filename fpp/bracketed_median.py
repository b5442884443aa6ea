"""The exact median of a large array, found by partitioning only the values near it.

``numpy.median`` partitions the whole array (introselect over every value). The median of ``n`` values lies, with
near certainty, between two order statistics of a sample of them a few of the sample's standard errors either side
of its middle: :func:`bracketed_median` takes every 64th value as the sample, counts the values below its bracket,
keeps those inside it and partitions those only (a few percent of the array). The counts prove the median inside
the bracket; where they do not (a rare sample, NaN in the array, a small array) it falls back to
``numpy.median``. The result is ``numpy.median``'s bit for bit: the same order statistics, averaged by the same
``numpy.mean`` when ``n`` is even.
"""
from __future__ import annotations

import numpy as np

__all__ = ["bracketed_median"]

#: Every this many-th value is the sample that brackets the median.
_SAMPLE_STEP = 64
#: Arrays smaller than this go to numpy.median whole (a bracket saves nothing there).
_MIN_SIZE = 8192
#: Half-width of the bracket around the sample's middle, in the sample median's standard errors (about
#: ``sqrt(r) / 2`` ranks of a sample of ``r``): a median outside it has odds of about 6e-5 (then numpy.median, the
#: same value at twice the cost). 4 rather than 6 partitions a third fewer values: 0.96 -> 0.76 ms on a 640x480
#: scan's ~270,000 float64 values, 0.81 -> 0.59 on float32 ones (docs/benchmarks.md, "Floor kernels, session 10").
_BRACKET_ERRORS = 4.0


def bracketed_median(values: np.ndarray) -> np.floating:
    """``numpy.median(values)`` of a 1-D array (a numpy scalar of its dtype), bit for bit, partitioning only the
    values near the median.

    Parameters
    ----------
    values : ndarray (n,)
        Any real dtype; NaN makes the result NaN (as numpy's).
    """
    v = np.asarray(values)
    if v.ndim != 1:
        raise ValueError(f"values must be a 1-D array; got shape {v.shape}")
    n = v.size
    if n < _MIN_SIZE:
        return np.median(v)
    sample = np.sort(v[::_SAMPLE_STEP])  # NaN sorts last
    reach = int(_BRACKET_ERRORS * 0.5 * np.sqrt(sample.size)) + 1
    lo = sample[max(0, sample.size // 2 - reach)]
    hi = sample[min(sample.size - 1, sample.size // 2 + reach)]
    below = np.count_nonzero(v < lo)
    inside = (v >= lo) & (v <= hi)
    inner = v[inside]
    above = np.count_nonzero(v > hi)
    first = (n - 1) // 2  # the median's (lower) order statistic, 0-based
    last = n // 2
    if below + inner.size + above != n or not (below <= first and last < below + inner.size):
        return np.median(v)  # NaN present, or the bracket missed: the whole array
    if first == last:
        return np.partition(inner, first - below)[first - below]
    part = np.partition(inner, [first - below, last - below])
    return np.mean(part[first - below:last - below + 1])
