"""Futures and tasks (``rclpy.task``): results that arrive later, e.g. a service response.

A :class:`Future` is thread-safe. ``result()`` does not block (None until done), as in rclpy; wait
with ``executor.spin_until_future_complete(future)`` or ``dptpu.graph.spin_until_future_complete``.
Service responses complete their futures from the runtime's I/O thread, so a future can complete
even while nothing spins (``client.call()`` therefore works inside a callback). Done callbacks run
as tasks of the executor the future belongs to, or at once in the completing thread when it has none.
"""

from __future__ import annotations

import threading
import weakref
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # executors imports this module: Executor is named for the type checker only
    from .executors import Executor

__all__ = ["Future", "Task"]


class Future:
    """The eventual result of an asynchronous operation."""

    def __init__(self, *, executor=None) -> None:
        self._lock = threading.Lock()
        self._event = threading.Event()
        self._done = False
        self._cancelled = False
        self._result = None
        self._exception = None
        self._callbacks: list = []
        self._hooks: list = []  # internal, run inline on completion (must be quick)
        self._executor: weakref.ref[Executor] | None = None
        if executor is not None:
            self._set_executor(executor)

    def done(self) -> bool:
        return self._done

    def cancelled(self) -> bool:
        return self._cancelled

    def cancel(self) -> None:
        """Mark the future cancelled (a request already sent is not recalled; its response is ignored)."""
        self._complete(cancelled=True)

    def result(self):
        """The result; None while not done; raises the exception the operation ended with."""
        if self._exception is not None:
            raise self._exception
        return self._result

    def exception(self):
        return self._exception

    def set_result(self, result) -> None:
        self._complete(result=result)

    def set_exception(self, exception) -> None:
        self._complete(exception=exception)

    def wait(self, timeout_sec=None) -> bool:
        """Block until done (not in rclpy; handy outside executors); True when done in time."""
        return self._event.wait(timeout_sec)

    def _complete(self, result=None, exception=None, cancelled=False) -> None:
        with self._lock:
            if self._done:
                return
            self._result, self._exception, self._cancelled = result, exception, cancelled
            self._done = True
            callbacks, self._callbacks = self._callbacks, []
            hooks, self._hooks = self._hooks, []
        self._event.set()
        for hook in hooks:
            hook(self)
        for callback in callbacks:
            self._schedule(callback)

    def _schedule(self, callback) -> None:
        executor = self._executor() if self._executor is not None else None
        if executor is not None:
            executor.create_task(callback, self)
        else:
            callback(self)

    def _set_executor(self, executor) -> None:
        self._executor = weakref.ref(executor)

    def add_done_callback(self, callback) -> None:
        """Call ``callback(future)`` when done (scheduled on the future's executor, if any)."""
        if not callable(callback):
            raise ValueError(f"callback must be callable; got {callback!r}")
        with self._lock:
            if not self._done:
                self._callbacks.append(callback)
                return
        self._schedule(callback)

    def _add_hook(self, hook) -> None:
        with self._lock:
            if not self._done:
                self._hooks.append(hook)
                return
        hook(self)

    def __repr__(self):
        state = "cancelled" if self._cancelled else "done" if self._done else "pending"
        return f"<{type(self).__name__} {state}>"


class Task(Future):
    """A callable run once by an executor; its return value becomes the result."""

    def __init__(self, handler, args=(), kwargs=None, *, executor=None):
        super().__init__(executor=executor)
        self._handler = handler
        self._args = args
        self._kwargs = kwargs or {}
        self._claimed = False
        self._claim_lock = threading.Lock()

    def _claim(self) -> bool:
        with self._claim_lock:
            if self._claimed or self._done:
                return False
            self._claimed = True
            return True

    def __call__(self) -> None:
        try:
            self.set_result(self._handler(*self._args, **self._kwargs))
        except Exception as exc:  # any exception: a task's failure is its result
            self.set_exception(exc)
            raise
