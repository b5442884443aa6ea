"""Clocks, times and durations with rclpy's names (``rclpy.clock``, ``rclpy.time``, ``rclpy.duration``).

A node's clock (``node.get_clock()``) is a ROS_TIME clock; simulated time is not implemented, so it
reads the system (wall) clock, like rclpy with ``use_sim_time`` false. Timers are scheduled on the
monotonic clock, so they are immune to wall-clock jumps.

Convention: times are integer nanoseconds since the Unix epoch (SYSTEM_TIME, ROS_TIME) or since an
arbitrary start (STEADY_TIME); ``Time.to_msg()`` gives a ``builtin_interfaces/msg/Time``.
"""

from __future__ import annotations

import time as _time
from enum import IntEnum

from ..messages.std import Time as TimeMsg

__all__ = ["ClockType", "Clock", "Time", "Duration", "NANOSECONDS_PER_SECOND"]

NANOSECONDS_PER_SECOND = 1_000_000_000


class ClockType(IntEnum):
    """rclpy's clock types."""

    UNINITIALIZED = 0
    ROS_TIME = 1
    SYSTEM_TIME = 2
    STEADY_TIME = 3


def _nanoseconds(seconds, nanoseconds, what: str) -> int:
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)):
        raise ValueError(f"{what} seconds must be a number; got {seconds!r}")
    if isinstance(nanoseconds, bool) or not isinstance(nanoseconds, int):
        raise ValueError(f"{what} nanoseconds must be an int; got {nanoseconds!r}")
    return int(round(seconds * NANOSECONDS_PER_SECOND)) + nanoseconds


class Duration:
    """A span of time, ``Duration(seconds=0, nanoseconds=0)``; ``.nanoseconds`` is the exact int."""

    __slots__ = ("_ns",)

    def __init__(self, *, seconds=0, nanoseconds=0):
        self._ns = _nanoseconds(seconds, nanoseconds, "Duration")

    @property
    def nanoseconds(self) -> int:
        return self._ns

    def seconds_nanoseconds(self) -> tuple[int, int]:
        return divmod(self._ns, NANOSECONDS_PER_SECOND)

    def __add__(self, other):
        if isinstance(other, Duration):
            return Duration(nanoseconds=self._ns + other._ns)
        return NotImplemented

    def __sub__(self, other):
        if isinstance(other, Duration):
            return Duration(nanoseconds=self._ns - other._ns)
        return NotImplemented

    def __mul__(self, factor):
        if isinstance(factor, (int, float)) and not isinstance(factor, bool):
            return Duration(nanoseconds=int(round(self._ns * factor)))
        return NotImplemented

    __rmul__ = __mul__

    def _cmp(self, other):
        if not isinstance(other, Duration):
            raise TypeError(f"cannot compare Duration with {type(other).__name__}")
        return self._ns, other._ns

    def __eq__(self, other):
        return isinstance(other, Duration) and self._ns == other._ns

    def __hash__(self):
        return hash(("Duration", self._ns))

    def __lt__(self, other):
        a, b = self._cmp(other)
        return a < b

    def __le__(self, other):
        a, b = self._cmp(other)
        return a <= b

    def __gt__(self, other):
        a, b = self._cmp(other)
        return a > b

    def __ge__(self, other):
        a, b = self._cmp(other)
        return a >= b

    def __repr__(self):
        return f"Duration(nanoseconds={self._ns})"


class Time:
    """A point in time of one clock type, ``Time(seconds=0, nanoseconds=0, clock_type=SYSTEM_TIME)``."""

    __slots__ = ("_ns", "_clock_type")

    def __init__(self, *, seconds=0, nanoseconds=0, clock_type=ClockType.SYSTEM_TIME):
        self._ns = _nanoseconds(seconds, nanoseconds, "Time")
        if self._ns < 0:
            raise ValueError(f"Time must not be negative; got {self._ns} ns")
        self._clock_type = ClockType(clock_type)

    @property
    def nanoseconds(self) -> int:
        return self._ns

    @property
    def clock_type(self) -> ClockType:
        return self._clock_type

    def seconds_nanoseconds(self) -> tuple[int, int]:
        """``(sec, nanosec)`` with ``0 <= nanosec < 1e9``."""
        return divmod(self._ns, NANOSECONDS_PER_SECOND)

    def to_msg(self) -> TimeMsg:
        """This time as a ``builtin_interfaces/msg/Time`` message (for ``header.stamp``)."""
        return TimeMsg.from_ns(self._ns)

    @classmethod
    def from_msg(cls, msg: TimeMsg, clock_type=ClockType.ROS_TIME) -> Time:
        if not isinstance(msg, TimeMsg):
            raise ValueError(f"msg must be a builtin_interfaces Time message; got {type(msg).__name__}")
        return cls(nanoseconds=msg.to_ns(), clock_type=clock_type)

    def __add__(self, other):
        if isinstance(other, Duration):
            return Time(nanoseconds=self._ns + other.nanoseconds, clock_type=self._clock_type)
        return NotImplemented

    __radd__ = __add__

    def __sub__(self, other):
        if isinstance(other, Time):
            if other._clock_type != self._clock_type:
                raise TypeError(f"cannot subtract times of different clocks ({self._clock_type.name} and "
                                f"{other._clock_type.name})")
            return Duration(nanoseconds=self._ns - other._ns)
        if isinstance(other, Duration):
            return Time(nanoseconds=self._ns - other.nanoseconds, clock_type=self._clock_type)
        return NotImplemented

    def _cmp(self, other):
        if not isinstance(other, Time):
            raise TypeError(f"cannot compare Time with {type(other).__name__}")
        if other._clock_type != self._clock_type:
            raise TypeError("cannot compare times of different clocks")
        return self._ns, other._ns

    def __eq__(self, other):
        return isinstance(other, Time) and (self._ns, self._clock_type) == (other._ns, other._clock_type)

    def __hash__(self):
        return hash((self._ns, self._clock_type))

    def __lt__(self, other):
        a, b = self._cmp(other)
        return a < b

    def __le__(self, other):
        a, b = self._cmp(other)
        return a <= b

    def __gt__(self, other):
        a, b = self._cmp(other)
        return a > b

    def __ge__(self, other):
        a, b = self._cmp(other)
        return a >= b

    def __repr__(self):
        return f"Time(nanoseconds={self._ns}, clock_type={self._clock_type.name})"


class Clock:
    """A clock: ``Clock(clock_type=ClockType.SYSTEM_TIME)``; ``now()`` returns a :class:`Time`."""

    def __init__(self, *, clock_type=ClockType.SYSTEM_TIME):
        clock_type = ClockType(clock_type)
        if clock_type == ClockType.UNINITIALIZED:
            raise ValueError("clock_type must be ROS_TIME, SYSTEM_TIME or STEADY_TIME; got UNINITIALIZED")
        self._clock_type = clock_type

    @property
    def clock_type(self) -> ClockType:
        return self._clock_type

    def now(self) -> Time:
        """The current time: wall clock for ROS_TIME and SYSTEM_TIME, monotonic for STEADY_TIME."""
        ns = _time.monotonic_ns() if self._clock_type == ClockType.STEADY_TIME else _time.time_ns()
        return Time(nanoseconds=ns, clock_type=self._clock_type)

    def __repr__(self):
        return f"Clock(clock_type={self._clock_type.name})"


class ROSClock(Clock):
    """A ROS_TIME clock (what ``node.get_clock()`` returns); ``ros_time_is_active`` is always False."""

    def __init__(self):
        super().__init__(clock_type=ClockType.ROS_TIME)

    @property
    def ros_time_is_active(self) -> bool:
        return False
