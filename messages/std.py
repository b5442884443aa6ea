"""Standard messages: ``builtin_interfaces/msg/Time`` and ``std_msgs/msg/Header`` (ROS 2 fields)."""

from __future__ import annotations

from .schema import Message, message, nested, scalar

__all__ = ["Time", "Header", "NANOSECONDS_PER_SECOND"]

NANOSECONDS_PER_SECOND = 1_000_000_000


@message("builtin_interfaces/msg/Time", version=1)
class Time(Message):
    """A point in time, ROS 2 ``builtin_interfaces/msg/Time``.

    Attributes
    ----------
    sec : int
        Whole seconds (int32), since the Unix epoch for wall-clock stamps.
    nanosec : int
        Nanoseconds past ``sec`` (uint32), in ``[0, 1e9)``.

    Convention: the time is ``sec + nanosec * 1e-9`` seconds; a negative time has a negative ``sec``
    and a non-negative ``nanosec`` (-0.25 s is ``Time(sec=-1, nanosec=750_000_000)``).
    """

    sec: int = scalar("int32")
    nanosec: int = scalar("uint32")

    @classmethod
    def from_ns(cls, nanoseconds: int) -> Time:
        """The time ``nanoseconds`` ns (an int, e.g. ``time.time_ns()``) after the epoch."""
        if isinstance(nanoseconds, bool) or not isinstance(nanoseconds, int):
            raise ValueError(f"nanoseconds must be an int; got {type(nanoseconds).__name__}")
        sec, nanosec = divmod(nanoseconds, NANOSECONDS_PER_SECOND)
        if not -(2**31) <= sec < 2**31:
            raise ValueError(f"nanoseconds out of the int32-seconds range of Time; got {nanoseconds}")
        return cls(sec=sec, nanosec=nanosec)

    def to_ns(self) -> int:
        """The time in integer nanoseconds, ``sec * 1e9 + nanosec`` (exact)."""
        return int(self.sec) * NANOSECONDS_PER_SECOND + int(self.nanosec)

    def check_consistency(self) -> None:
        if self.nanosec >= NANOSECONDS_PER_SECOND:
            raise ValueError(f"Time.nanosec must be < 1e9; got {self.nanosec}")


@message("std_msgs/msg/Header", version=1)
class Header(Message):
    """Stamp and coordinate frame of a message, ROS 2 ``std_msgs/msg/Header``.

    Attributes
    ----------
    stamp : Time
        When the data was acquired (for images: exposure start).
    frame_id : str
        The coordinate frame the data is expressed in, e.g. ``"scanner_optical_frame"``.
    """

    stamp: Time = nested(Time)
    frame_id: str = scalar("string")
