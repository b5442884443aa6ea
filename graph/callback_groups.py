"""Callback groups: which callbacks a multi-threaded executor may run at the same time (rclpy's model).

Every node has a default :class:`MutuallyExclusiveCallbackGroup`: its callbacks never run
concurrently, even in a :class:`~dptpu.graph.executors.MultiThreadedExecutor`. Put callbacks in a
:class:`ReentrantCallbackGroup` (or in different mutually exclusive groups) to let them overlap.
"""

from __future__ import annotations

import threading

__all__ = ["CallbackGroup", "MutuallyExclusiveCallbackGroup", "ReentrantCallbackGroup"]


class CallbackGroup:
    """Base class: decides whether one more callback of the group may start now."""

    def __init__(self):
        self._lock = threading.Lock()
        self._running = 0

    def can_execute(self, entity=None) -> bool:
        raise NotImplementedError

    def beginning_execution(self, entity=None) -> bool:
        """Claim a slot; False when the group may not start another callback now."""
        with self._lock:
            if not self._can_execute_locked():
                return False
            self._running += 1
            return True

    def ending_execution(self, entity=None) -> None:
        with self._lock:
            self._running = max(0, self._running - 1)

    def _can_execute_locked(self) -> bool:
        raise NotImplementedError


class MutuallyExclusiveCallbackGroup(CallbackGroup):
    """At most one callback of the group runs at a time."""

    def can_execute(self, entity=None) -> bool:
        with self._lock:
            return self._running == 0

    def _can_execute_locked(self) -> bool:
        return self._running == 0


class ReentrantCallbackGroup(CallbackGroup):
    """Any number of callbacks of the group (even the same one) may run at once."""

    def can_execute(self, entity=None) -> bool:
        return True

    def _can_execute_locked(self) -> bool:
        return True
