"""dptpu.fpp.bracketed_median: numpy.median's value bit for bit, on the arrays it is used on and on hard ones."""
import numpy as np
import pytest

from dptpu.fpp.bracketed_median import bracketed_median


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("size", [9, 20_000, 20_001, 300_000])
def test_the_median_is_numpys_bit_for_bit(dtype, size):
    rng = np.random.default_rng(size)
    arrays = [rng.normal(0.0, 1.0, size), rng.lognormal(0.0, 2.0, size),  # noise maps are skewed
              np.round(rng.normal(0.0, 3.0, size)),  # many ties
              np.full(size, 0.7),  # all ties
              np.sort(rng.random(size)),  # sorted: every 64th value an even sample
              np.r_[np.zeros(size // 2), np.ones(size - size // 2)]]  # the median between two plateaus
    for values in arrays:
        values = values.astype(dtype)
        expected = np.median(values)
        got = bracketed_median(values)
        assert got == expected and np.asarray(got).dtype == np.asarray(expected).dtype


def test_nan_and_a_missed_bracket_fall_back_to_numpy():
    rng = np.random.default_rng(1)
    values = rng.random(50_000)
    values[7] = np.nan
    assert np.isnan(bracketed_median(values))
    values = np.r_[np.zeros(25_000), rng.random(25_000) + 1.0]
    values[::64] = 5.0  # the sample sees only large values: its bracket misses the median
    assert bracketed_median(values) == np.median(values)
    with pytest.raises(ValueError, match="1-D"):
        bracketed_median(np.zeros((3, 3)))
