"""Timers (run a callback every period, in the executor) and rates (sleep to keep a loop at a frequency).

Timers are scheduled on the monotonic clock. When a callback overruns one or more periods, the
missed calls are skipped (as rcl does): the next call is the next multiple of the period from the
start, never a burst of catch-up calls.
"""

from __future__ import annotations

import threading
import time

__all__ = ["Timer", "Rate"]

_NS = 1_000_000_000


class Timer:
    """Calls ``callback()`` every ``timer_period_ns`` (create with ``node.create_timer``)."""

    def __init__(self, node, callback, timer_period_sec: float, callback_group, *, autostart: bool = True):
        if isinstance(timer_period_sec, bool) or not isinstance(timer_period_sec, (int, float)) \
                or not timer_period_sec >= 0:
            raise ValueError(f"timer_period_sec must be a number >= 0 (seconds); got {timer_period_sec!r}")
        if not callable(callback):
            raise ValueError(f"timer callback must be callable; got {callback!r}")
        self._node = node
        self.callback = callback
        self.callback_group = callback_group
        self._period_ns = int(round(timer_period_sec * _NS))
        self._lock = threading.Lock()
        self._canceled = not autostart
        self._next_ns = time.monotonic_ns() + self._period_ns
        self._last_call_ns = time.monotonic_ns()
        self.exception_count = 0
        self._destroyed = False

    @property
    def timer_period_ns(self) -> int:
        return self._period_ns

    @timer_period_ns.setter
    def timer_period_ns(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"timer_period_ns must be an int >= 0; got {value!r}")
        with self._lock:
            self._period_ns = value
            self._next_ns = self._last_call_ns + value
        self._node._notify_executor()

    def is_canceled(self) -> bool:
        return self._canceled

    def cancel(self) -> None:
        self._canceled = True

    def reset(self) -> None:
        """Restart the period from now (and un-cancel)."""
        with self._lock:
            self._canceled = False
            self._next_ns = time.monotonic_ns() + self._period_ns
        self._node._notify_executor()

    def is_ready(self) -> bool:
        return self._ready(time.monotonic())

    def time_since_last_call(self) -> int:
        """Nanoseconds since the last call (or since creation)."""
        return time.monotonic_ns() - self._last_call_ns

    def time_until_next_call(self) -> int | None:
        """Nanoseconds until the next call; None when canceled."""
        return None if self._canceled else max(0, self._next_ns - time.monotonic_ns())

    def destroy(self) -> bool:
        return self._node.destroy_timer(self)

    # -- executor side ------------------------------------------------------------------------------

    def _deadline(self) -> float | None:
        """Monotonic seconds of the next call, None when canceled."""
        return None if self._canceled or self._destroyed else self._next_ns / _NS

    def _ready(self, now: float) -> bool:
        return not self._canceled and not self._destroyed and now * _NS >= self._next_ns

    def _take(self):
        now_ns = time.monotonic_ns()
        with self._lock:
            if self._canceled or self._destroyed or now_ns < self._next_ns:
                return None
            period = max(self._period_ns, 1)
            missed = (now_ns - self._next_ns) // period
            self._next_ns += (missed + 1) * period
            self._last_call_ns = now_ns
        return self.callback

    def _describe(self) -> str:
        return f"timer callback (period {self._period_ns / _NS:g} s)"

    def __repr__(self):
        return f"<Timer period={self._period_ns / _NS:g}s{' canceled' if self._canceled else ''}>"


class Rate:
    """Keeps a loop at ``frequency`` Hz: ``rate.sleep()`` sleeps until the next period.

    Unlike rclpy's Rate it needs no executor spinning in another thread.
    """

    def __init__(self, frequency: float, *, context=None):
        if isinstance(frequency, bool) or not isinstance(frequency, (int, float)) or not frequency > 0:
            raise ValueError(f"frequency must be a number > 0 (Hz); got {frequency!r}")
        self._period = 1.0 / frequency
        self._next = time.monotonic() + self._period
        self._context = context
        self._destroyed = False

    def sleep(self) -> None:
        """Sleep until the next period starts (at once when the loop fell behind)."""
        now = time.monotonic()
        if self._next > now:
            time.sleep(self._next - now)
            self._next += self._period
        else:
            self._next = now + self._period

    def destroy(self) -> None:
        self._destroyed = True
