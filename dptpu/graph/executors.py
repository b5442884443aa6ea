"""Executors: run the callbacks of nodes (``rclpy.executors``).

An executor waits until something is ready (a message in a subscription's queue, a due timer, a
service request, a task) and runs its callback. The runtime's I/O thread fills the queues and wakes
the executor; the executor never touches a socket.

- :class:`SingleThreadedExecutor` runs one callback at a time in the thread that spins.
- :class:`MultiThreadedExecutor` runs callbacks on ``num_threads`` threads; callbacks of one
  :class:`~dptpu.graph.callback_groups.MutuallyExclusiveCallbackGroup` (each node's default) never overlap.

An exception raised by a callback is logged (ERROR, with the node, the topic/service/timer and the
traceback), counted on the entity (``exception_count``), and the executor goes on. Pass
``raise_callback_exceptions=True`` to let it propagate out of ``spin`` instead (rclpy's behaviour).
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from .context import get_default_context
from .logging import get_logger
from .task import Task

__all__ = ["Executor", "SingleThreadedExecutor", "MultiThreadedExecutor", "WakeSignal", "ShutdownException"]

_MAX_WAIT_S = 0.5  # an idle executor re-checks the context this often


class ShutdownException(Exception):
    """The executor was shut down (rclpy's name)."""


class WakeSignal:
    """A condition with a generation counter: waiting never misses a notify that came after ``generation()``."""

    def __init__(self):
        self._cond = threading.Condition(threading.Lock())
        self._generation = 0

    def generation(self) -> int:
        return self._generation

    def notify(self) -> None:
        with self._cond:
            self._generation += 1
            self._cond.notify_all()

    def wait(self, generation: int, timeout: float | None) -> None:
        with self._cond:
            if self._generation == generation:
                self._cond.wait(timeout)


class _TaskEntity:
    """Adapter that lets executor tasks go through the same loop as callbacks."""

    callback_group = None
    exception_count = 0

    def __init__(self, task: Task, node=None):
        self.task = task
        self._node = node

    def _ready(self, now):
        return not self.task._claimed and not self.task.done()

    def _take(self):
        return self.task if self.task._claim() else None

    def _describe(self):
        return "task"


class Executor:
    """Base class: node bookkeeping, finding ready work, waiting.

    Parameters
    ----------
    context : Context, optional
        Default: the default context.
    raise_callback_exceptions : bool
        Re-raise a callback's exception out of ``spin``/``spin_once`` instead of logging it.
    """

    _notify_after_run = True

    def __init__(self, *, context=None, raise_callback_exceptions: bool = False):
        self._context = context if context is not None else get_default_context()
        self._raise = raise_callback_exceptions
        self._nodes: list = []
        self._nodes_lock = threading.Lock()
        self._wake = WakeSignal()
        self._tasks: list[_TaskEntity] = []
        self._tasks_lock = threading.Lock()
        self._round_robin = 0
        self._take_lock = threading.Lock()
        self._is_shutdown = False
        self._context._track_executor(self)

    @property
    def context(self):
        return self._context

    def add_node(self, node) -> bool:
        """Add ``node``; False if it is already here. A node belongs to at most one executor."""
        with self._nodes_lock:
            if node in self._nodes:
                return False
            current = node.executor
            if current is not None and current is not self:
                current.remove_node(node)
            self._nodes.append(node)
            node._set_executor(self)
        self._wake.notify()
        return True

    def remove_node(self, node) -> None:
        with self._nodes_lock:
            if node in self._nodes:
                self._nodes.remove(node)
                node._set_executor(None)
        self._wake.notify()

    def get_nodes(self) -> list:
        with self._nodes_lock:
            return list(self._nodes)

    def create_task(self, callback, *args, **kwargs) -> Task:
        """Run ``callback(*args, **kwargs)`` soon in this executor; returns its :class:`Task`."""
        task = Task(callback, args, kwargs, executor=self)
        with self._tasks_lock:
            self._tasks.append(_TaskEntity(task))
        self._wake.notify()
        return task

    def wake(self) -> None:
        self._wake.notify()

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        """Stop spinning and release the nodes; True when done within ``timeout_sec``."""
        self._is_shutdown = True
        self._wake.notify()
        with self._nodes_lock:
            for node in self._nodes:
                node._set_executor(None)
            self._nodes.clear()
        return True

    # -- finding work ---------------------------------------------------------------------------------

    def _entities(self) -> list:
        with self._nodes_lock:
            nodes = list(self._nodes)
        entities = []
        for node in nodes:
            entities.extend(node._work)
        if self._tasks:
            with self._tasks_lock:
                self._tasks = [t for t in self._tasks if not t.task.done() and not t.task._claimed]
                entities.extend(self._tasks)
        return entities

    def _take_ready(self):
        """``(entity, work, group)`` of one ready callback whose group may run now, or None."""
        with self._take_lock:
            entities = self._entities()
            if not entities:
                return None
            now = time.monotonic()
            count = len(entities)
            start = self._round_robin % count
            for offset in range(count):
                entity = entities[(start + offset) % count]
                if not entity._ready(now):
                    continue
                group = entity.callback_group
                if group is not None and not group.beginning_execution(entity):
                    continue
                work = entity._take()
                if work is None:
                    if group is not None:
                        group.ending_execution(entity)
                    continue
                self._round_robin = (start + offset + 1) % count
                return entity, work, group
        return None

    def _next_deadline(self) -> float | None:
        deadline = None
        with self._nodes_lock:
            nodes = list(self._nodes)
        for node in nodes:
            for entity in node._work:
                next_call = getattr(entity, "_deadline", None)
                if next_call is not None:
                    value = next_call()
                    if value is not None and (deadline is None or value < deadline):
                        deadline = value
        return deadline

    def _run(self, entity, work, group) -> None:
        try:
            work()
        except Exception as exc:  # noqa: BLE001 -- a callback's failure must not kill the node
            entity.exception_count = getattr(entity, "exception_count", 0) + 1
            if isinstance(entity, _TaskEntity):
                get_logger("dptpu.graph").error(f"exception in an executor task: {type(exc).__name__}: {exc}",
                                                exc_info=(type(exc), exc, exc.__traceback__))
                return  # the task also holds the exception as its result
            else:
                node = entity._node
                node.get_logger().error(
                    f"exception in {entity._describe()} of node {node.get_fully_qualified_name()}: "
                    f"{type(exc).__name__}: {exc}", exc_info=(type(exc), exc, exc.__traceback__))
            if self._raise:
                raise
        finally:
            if group is not None:
                group.ending_execution(entity)
                if self._notify_after_run:
                    self._wake.notify()  # another thread may wait for this group to be free

    def _wait_for_work(self, timeout_sec):
        """Wait until work is taken (returned) or the timeout passes (None)."""
        deadline = None if timeout_sec is None or timeout_sec < 0 else time.monotonic() + timeout_sec
        while True:
            if self._is_shutdown or not self._context.ok():
                return None
            generation = self._wake.generation()
            found = self._take_ready()
            if found is not None:
                return found
            now = time.monotonic()
            wait = _MAX_WAIT_S
            if deadline is not None:
                if now >= deadline:
                    return None
                wait = min(wait, deadline - now)
            timer_deadline = self._next_deadline()
            if timer_deadline is not None:
                wait = min(wait, max(0.0, timer_deadline - now))
            if wait > 0:
                self._wake.wait(generation, wait)

    # -- spinning -------------------------------------------------------------------------------------

    def spin_once(self, timeout_sec: float | None = None) -> None:
        raise NotImplementedError

    def spin(self) -> None:
        """Run callbacks until the context shuts down or the executor is shut down."""
        while self._context.ok() and not self._is_shutdown:
            self.spin_once()

    def spin_until_future_complete(self, future, timeout_sec: float | None = None) -> None:
        """Spin until ``future`` is done (or ``timeout_sec`` passes)."""
        future._add_hook(lambda _f: self._wake.notify())
        deadline = None if timeout_sec is None or timeout_sec < 0 else time.monotonic() + timeout_sec
        while self._context.ok() and not self._is_shutdown and not future.done():
            if deadline is None:
                self.spin_once(timeout_sec=_MAX_WAIT_S)
            else:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return
                self.spin_once(timeout_sec=remaining)

    def spin_once_until_future_complete(self, future, timeout_sec: float | None = None) -> None:
        future._add_hook(lambda _f: self._wake.notify())
        if not future.done():
            self.spin_once(timeout_sec=timeout_sec)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.shutdown()


class SingleThreadedExecutor(Executor):
    """Runs every callback in the thread that calls ``spin``."""

    _notify_after_run = False  # nobody else waits for a callback group to be free

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Run at most one ready callback, waiting up to ``timeout_sec`` (None: until there is one)."""
        found = self._wait_for_work(timeout_sec)
        if found is not None:
            self._run(*found)


class MultiThreadedExecutor(Executor):
    """Runs callbacks on a pool of ``num_threads`` threads (default: the CPU count, at least 2)."""

    def __init__(self, num_threads: int | None = None, *, context=None, raise_callback_exceptions: bool = False):
        super().__init__(context=context, raise_callback_exceptions=raise_callback_exceptions)
        if num_threads is None:
            num_threads = max(os.cpu_count() or 2, 2)
        if isinstance(num_threads, bool) or not isinstance(num_threads, int) or num_threads < 1:
            raise ValueError(f"num_threads must be an int >= 1; got {num_threads!r}")
        self._num_threads = num_threads
        self._pool = ThreadPoolExecutor(max_workers=num_threads, thread_name_prefix="dptpu-executor")
        self._slots = threading.Semaphore(num_threads)
        self._submit_lock = threading.Lock()
        self._errors: list = []

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Start at most one ready callback on the pool (waiting up to ``timeout_sec`` for one)."""
        if self._errors:
            raise self._errors.pop(0)
        deadline = None if timeout_sec is None or timeout_sec < 0 else time.monotonic() + timeout_sec
        while not self._slots.acquire(timeout=_MAX_WAIT_S if deadline is None
                                      else max(0.0, min(_MAX_WAIT_S, deadline - time.monotonic()))):
            if self._is_shutdown or not self._context.ok() or (deadline is not None and time.monotonic() >= deadline):
                return
        remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
        found = self._wait_for_work(remaining)
        if found is None:
            self._slots.release()
            return
        with self._submit_lock:
            if not self._is_shutdown:
                self._pool.submit(self._run_in_pool, *found)
                return
        entity, _work, group = found  # shut down meanwhile: the taken callback is not run
        if group is not None:
            group.ending_execution(entity)
        self._slots.release()

    def _run_in_pool(self, entity, work, group) -> None:
        try:
            self._run(entity, work, group)
        except Exception as exc:  # noqa: BLE001 -- raise_callback_exceptions: hand it to the spinning thread
            self._errors.append(exc)
        finally:
            self._slots.release()
            self._wake.notify()

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        with self._submit_lock:
            super().shutdown(timeout_sec)
        self._pool.shutdown(wait=timeout_sec is None or timeout_sec > 0, cancel_futures=True)
        return True

