"""One rule for frequencies (fpp/frequencies.py): when two are the same, and which ones a method uses."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.frequencies import FREQUENCY_RELATIVE_TOLERANCE, find_frequency, same_frequency, select_frequencies
from dptpu.fpp.methods import CAPTURE_METHODS, PHASE_SEQUENCE_METHODS, TWO_FREQUENCY_METHODS


@pytest.mark.parametrize("value", [10.9, 1920 / 42, 912 / 45, 1.0, 96.0])
def test_a_rational_frequency_is_itself_through_float32_float64_and_printing(value):
    assert same_frequency(float(np.float32(value)), value)  # the wire's and the frames' float32
    assert same_frequency(float(repr(value)), value)  # YAML, msgpack: float64
    assert same_frequency(float(f"{value:g}"), value)  # what every message prints
    assert same_frequency(float(f"{value:.5g}"), value)  # typed with 5 significant digits (45.714, 20.267)


def test_frequencies_one_scan_can_use_together_are_different():
    assert not same_frequency(64.0, 63.0) and not same_frequency(1.0, 0.5)
    assert not same_frequency(200.0, 199.5)  # a beat of 0.5 at f = 200: mw's 1 / 400 relative
    assert same_frequency(1000.0, 1000.0 * (1 + 0.5 * FREQUENCY_RELATIVE_TOLERANCE))


def test_selection_follows_dptpu_unwrap():
    assert select_frequencies("mf", [1.0, 16.0, 15.0]) == [1, 0]
    assert select_frequencies("mw", [16.0, 1.0, 15.0]) == [0, 2]
    assert select_frequencies("nt", [16.0, 15.0]) == [0, 1]
    assert select_frequencies("heterodyne", [13.0, 16.0, 15.0]) == [1, 2, 0]
    assert select_frequencies("mf", [16.0, 1.0, 8.0], high=8.0) == [2, 1]
    assert select_frequencies("mf", [1920 / 42, 1.0], high=45.714) == [0, 1]
    assert select_frequencies("nt", [16.0, 8.0, 10.9], high=16.0, low=float(np.float32(10.9))) == [0, 2]
    assert select_frequencies("mf", [16.0, 1.0, 8.0, 8.0]) == [0, 1]  # a repeated frequency it does not use


@pytest.mark.parametrize("method, frequencies, options, message", [
    ("mf", [16.0, 15.0], {}, "mf needs a low frequency <= 1 .*; the scan has frequencies 16, 15: use heterodyne or nt"),
    ("nt", [16.0, 15.0, 1.0], {}, "nt takes the one other frequency by default, but the scan has frequencies 16, 15,"),
    ("mw", [16.0, 1.0], {}, r"mw needs a low frequency with 0 < f_h - f_l <= 1 for f_h = 16; the scan has"),
    ("mw", [16.0, 16.0], {}, "frequency 16 appears 2 times; mw needs the frequencies it uses to be distinct"),
    ("heterodyne", [16.0, 15.0, 15.0], {}, "frequency 15 appears 2 times"),
    ("heterodyne", [16.0, 15.0], {"high": 15.0}, "heterodyne unwraps with every frequency and gives the highest"),
    ("mf", [16.0, 1.0], {"high": 32.0}, r"unknown frequency 32 \(high\); the scan has frequencies 16, 1"),
    ("mf", [16.0, 1.0], {"high": 16.0, "low": 16.0}, "low 16 is the high frequency 16; the low one must be another"),
    ("mf", [16.0, 1.0], {"low": -1.0}, "low must be a frequency > 0; got -1"),
    ("mf", [16.0], {}, "mf needs two or more frequencies; the scan has frequencies 16"),
    ("graycode", [16.0, 1.0], {}, "unknown unwrapping method 'graycode'"),
])
def test_selection_says_what_the_scan_lacks(method, frequencies, options, message):
    with pytest.raises(ValueError, match=message):
        select_frequencies(method, frequencies, **options)


def test_messages_name_the_callers_options_and_what_it_has():
    with pytest.raises(ValueError, match=r"^unknown frequency 50 \(--high\); the capture has 64, 1$"):
        select_frequencies("mf", [64.0, 1.0], high=50, options=("--high", "--low"), context="the capture has 64, 1")
    with pytest.raises(ValueError, match=r"2 frequencies are 8 \(low_frequency\)"):
        find_frequency([8.0, 8.0, 16.0], 8.0, option="low_frequency")


def test_method_families_nest():
    assert TWO_FREQUENCY_METHODS == ("mf", "mw", "nt")
    assert PHASE_SEQUENCE_METHODS == (*TWO_FREQUENCY_METHODS, "heterodyne")
    assert CAPTURE_METHODS == (*PHASE_SEQUENCE_METHODS, "graycode")
