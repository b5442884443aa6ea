"""Tests for dptpu.fpp.patterns: projector fringe sequences (Eq. (1) of the paper)."""

import numpy as np
import pytest

from dptpu.fpp.patterns import frequency_from_period, fringe_patterns, projector_phase


def test_frequency_from_period_is_extent_over_period():
    assert frequency_from_period(9.5, 912) == pytest.approx(96.0)
    assert frequency_from_period(period=60, extent=912) == pytest.approx(15.2)


@pytest.mark.parametrize(
    "bit_depth, dtype, full_scale", [(8, np.uint8, 255), (16, np.uint16, 65535)]
)
def test_shape_dtype_and_levels_for_bit_depth(bit_depth, dtype, full_scale):
    patterns = fringe_patterns(frequency=4, steps=5, projector_size=(96, 64), bit_depth=bit_depth)
    assert patterns.shape == (5, 64, 96)
    assert patterns.dtype == dtype
    # Image 0 at x_p = 0 has phi = 0: level = round(full * (0.5 + 0.45)).
    assert patterns[0, 0, 0] == round(full_scale * 0.95)
    # Quantized = rounded unquantized levels.
    levels = fringe_patterns(
        frequency=4, steps=5, projector_size=(96, 64), bit_depth=bit_depth, dtype=float
    )
    assert levels.dtype == np.float64
    np.testing.assert_array_equal(patterns, np.rint(levels).astype(dtype))
    assert levels.min() >= full_scale * 0.05 - 1e-9
    assert levels.max() <= full_scale * 0.95 + 1e-9


def test_axis_x_varies_along_columns_and_axis_y_along_rows():
    size = (48, 40)  # width, height
    along_x = fringe_patterns(frequency=3, steps=4, projector_size=size, axis="x", dtype=float)
    along_y = fringe_patterns(frequency=3, steps=4, projector_size=size, axis="y", dtype=float)
    assert along_x.shape == along_y.shape == (4, 40, 48)
    assert np.ptp(along_x, axis=1).max() == 0.0  # constant down each column
    assert np.ptp(along_y, axis=2).max() == 0.0  # constant along each row
    # axis="y" uses the height as extent: phi(y) = 2*pi*3*y/40.
    y = np.arange(40)
    expected = 255 * (0.5 + 0.45 * np.cos(2 * np.pi * 3 * y / 40 - 2 * np.pi * 1 / 4))
    np.testing.assert_allclose(along_y[1, :, 0], expected, atol=1e-9)


def test_rational_frequency_phase_of_pixel():
    width, height = 912, 4
    phase = projector_phase((width, height), 10.9)
    x = np.arange(width)
    np.testing.assert_allclose(phase[2], 2 * np.pi * 10.9 * x / width, rtol=0, atol=1e-12)
    assert phase[0, 500] == pytest.approx(2 * np.pi * 10.9 * 500 / 912, abs=1e-12)
    # The patterns carry that phase: image n = 0.5 + 0.45 cos(phi - 2 pi n / N).
    levels = fringe_patterns(
        frequency=10.9, steps=3, projector_size=(width, height), dtype=float
    )
    for n in range(3):
        expected = 255 * (0.5 + 0.45 * np.cos(2 * np.pi * 10.9 * x / width - 2 * np.pi * n / 3))
        np.testing.assert_allclose(levels[n, 1], expected, atol=1e-9)


def test_period_and_frequency_give_the_same_patterns():
    by_period = fringe_patterns(period=12, steps=4, projector_size=(96, 20))
    by_frequency = fringe_patterns(frequency=8, steps=4, projector_size=(96, 20))
    np.testing.assert_array_equal(by_period, by_frequency)
    common = dict(steps=3, projector_size=(16, 50), axis="y", dtype=float)
    by_period_y = fringe_patterns(period=10, **common)
    by_frequency_y = fringe_patterns(frequency=5, **common)
    np.testing.assert_allclose(by_period_y, by_frequency_y, atol=1e-9)


def test_convention_phase_increases_with_projector_column():
    # N = 4, sign -1: I0 = o + a cos(phi), I1 = o + a cos(phi - pi/2) = o + a sin(phi).
    levels = fringe_patterns(frequency=2, steps=4, projector_size=(64, 1), dtype=float)[:, 0]
    phi = np.unwrap(np.arctan2(levels[1] - levels[3], levels[0] - levels[2]))
    steps_rad = np.diff(phi)
    np.testing.assert_allclose(steps_rad, 2 * np.pi * 2 / 64, atol=1e-12)  # increasing with column
    assert phi[0] == pytest.approx(0.0, abs=1e-12)  # first pixel centre has phase 0


def test_shift_sign_and_phase_offset():
    plus = fringe_patterns(
        frequency=1, steps=3, projector_size=(30, 1), shift_sign=1, phase_offset=0.25, dtype=float
    )
    x = np.arange(30)
    expected = 255 * (0.5 + 0.45 * np.cos(2 * np.pi * x / 30 + 0.25 + 2 * np.pi * 2 / 3))
    np.testing.assert_allclose(plus[2, 0], expected, atol=1e-9)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(frequency=2, period=10), "exactly one of frequency and period"),
        (dict(), "exactly one of frequency and period"),
        (dict(frequency=2, steps=2), "steps must be an integer >= 3; got 2"),
        (dict(frequency=-1), "frequency must be > 0"),
        (dict(period=0), "period must be > 0"),
        (dict(frequency=2, offset=0.6, amplitude=0.45), r"within \[0, 1\]"),
        (dict(frequency=2, bit_depth=12), "bit_depth must be one of"),
        (dict(frequency=2, shift_sign=0), "shift_sign must be -1 or \\+1"),
        (dict(frequency=2, axis="z"), "axis must be 'x' or 'y'"),
        (dict(frequency=2, projector_size=(0, 10)), "width must be a positive integer"),
        (dict(frequency=2, projector_size=(10,)), r"projector_size must be \(width, height\)"),
    ],
)
def test_bad_input_raises(kwargs, message):
    arguments = dict(steps=4, projector_size=(32, 8))
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message):
        fringe_patterns(**arguments)
