"""builtin_interfaces/Time and std_msgs/Header."""

from __future__ import annotations

import pytest

from dptpu.messages import Header, Time, decode, encode


def test_time_from_ns_and_back_is_exact():
    stamp = Time.from_ns(1_700_000_000_123_456_789)
    assert (stamp.sec, stamp.nanosec) == (1_700_000_000, 123_456_789)
    assert stamp.to_ns() == 1_700_000_000_123_456_789


def test_negative_time_has_non_negative_nanosec():
    stamp = Time.from_ns(-250_000_000)
    assert (stamp.sec, stamp.nanosec) == (-1, 750_000_000)
    assert stamp.to_ns() == -250_000_000


def test_time_checks():
    with pytest.raises(ValueError, match=r"nanoseconds must be an int; got float"):
        Time.from_ns(1.5)
    with pytest.raises(ValueError, match=r"nanoseconds out of the int32-seconds range of Time; got "):
        Time.from_ns(2**31 * 10**9)
    with pytest.raises(ValueError, match=r"Time.nanosec must be < 1e9; got 1000000000"):
        encode("/clock", Time(sec=0, nanosec=1_000_000_000))


def test_header_defaults_and_round_trip():
    assert Header() == Header(stamp=Time(sec=0, nanosec=0), frame_id="")
    header = Header(stamp=Time(sec=12, nanosec=5), frame_id="scanner_optical_frame")
    topic, decoded = decode(encode(b"/header", header))
    assert topic == "/header" and decoded == header and decoded != Header()
    assert decoded.stamp.to_ns() == 12_000_000_005
