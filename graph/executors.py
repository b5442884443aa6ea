"""Executors: run the callbacks of nodes (``rclpy.executors``).

An executor waits until something is ready (a message in a subscription's queue, a due timer, a
service request, a task) and runs its callback. While it waits, it receives from the subscription
sockets of its nodes itself: the runtime's I/O thread lends them to it (:mod:`dptpu.graph.lease`), so
a message reaches its callback without changing threads. While the executor runs callbacks for longer
than :data:`~dptpu.graph.lease.TAKEOVER_S`, or does not spin, the I/O thread drains those sockets
into the subscriptions' queues and wakes the executor, as it does for service requests and responses.

- :class:`SingleThreadedExecutor` runs one callback at a time in the thread that spins.
- :class:`MultiThreadedExecutor` runs callbacks on ``num_threads`` threads; callbacks of one
  :class:`~dptpu.graph.callback_groups.MutuallyExclusiveCallbackGroup` (each node's default) never overlap.

An exception raised by a callback is logged (ERROR, with the node, the topic/service/timer and the
traceback), counted on the entity (``exception_count``), and the executor goes on. Pass
``raise_callback_exceptions=True`` to let it propagate out of ``spin`` instead (rclpy's behaviour).
"""

from __future__ import annotations

import math
import os
import threading
import time
import weakref
from concurrent.futures import ThreadPoolExecutor

import zmq
from zmq import zmq_poll

from .context import get_default_context
from .lease import BUSY, IO
from .logging import get_logger
from .task import Task

__all__ = ["Executor", "SingleThreadedExecutor", "MultiThreadedExecutor", "WakeSignal", "ShutdownException"]

_MAX_WAIT_S = 0.5  # an idle executor re-checks the context this often
#: While callbacks keep an executor busy, it drains its lent sockets (without waiting) at least this often.
_PUMP_INTERVAL_S = 0.002
#: A poll that returned sooner than this did not wait: messages may be piling up, so drain every socket fully.
_NO_WAIT_S = 50e-6


class ShutdownException(Exception):
    """The executor was shut down (rclpy's name)."""


def _close_fds(*fds) -> None:
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass


class WakeSignal:
    """A generation counter and a pipe: waiting never misses a notify that came after ``generation()``.

    The waiting side is a ``zmq_poll`` that includes the pipe's read end (:attr:`fd`), so one wait
    covers both a notify and data on the executor's lent sockets. ``notify`` writes to the pipe only
    while a thread waits.
    """

    def __init__(self):
        self._lock = threading.Lock()
        self._generation = 0
        self._waiters = 0
        self._armed = False  # a byte is in the pipe
        self.fd, self._write_fd = os.pipe()
        os.set_blocking(self.fd, False)
        os.set_blocking(self._write_fd, False)
        self._pipe_poller = zmq.Poller()
        self._pipe_poller.register(self.fd, zmq.POLLIN)
        weakref.finalize(self, _close_fds, self.fd, self._write_fd)

    def generation(self) -> int:
        return self._generation

    def notify(self) -> None:
        with self._lock:
            self._generation += 1
            if self._waiters and not self._armed:
                self._armed = True
                try:
                    os.write(self._write_fd, b"\0")
                except OSError:
                    pass

    def wait(self, generation: int, timeout: float | None, poller=None):
        """Wait until notified or ``timeout`` seconds (None: forever) pass, unless notified since ``generation``.

        ``poller``: a ``zmq.Poller`` that includes :attr:`fd` (and sockets). Returns its ready list, or
        None when a notify came after ``generation`` (then nothing was polled).
        """
        with self._lock:
            if self._generation != generation:
                return None
            self._waiters += 1
        try:
            # whole ms, rounded up: zmq_poll truncates, and waking early would spin until the deadline
            # zmq_poll on the Poller's own item list (what Poller.poll calls, less one Python frame)
            timeout_ms = -1 if timeout is None else math.ceil(timeout * 1000.0)
            ready = zmq_poll((poller or self._pipe_poller).sockets, timeout_ms)
        finally:
            with self._lock:
                self._waiters -= 1
                if not self._waiters and self._armed:
                    self._armed = False
                    try:
                        while os.read(self.fd, 4096):
                            pass
                    except OSError:
                        pass
        return ready


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
        self._lease = None  # SocketLease with the context's runtime, made on the first wait
        self._last_poll = 0.0
        # (the nodes' _work tuples, their entities, the timers among them, their ready queues)
        self._entity_cache: tuple = ([], [], [], [])
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
        lease = self._lease
        if lease is not None and not lease.covers(node):
            lease.invalidate()  # lend this node's sockets too
        self._wake.notify()
        return True

    def remove_node(self, node) -> None:
        """Remove ``node``. Its sockets stay lent to this executor until the runtime takes them back (when
        another executor needs them, or this one does not poll for a while); meanwhile what this executor
        receives for the node goes into its queues and wakes the node's executor, if it has one. So
        ``spin_once(node)``, which adds and removes the node each time, does not hand sockets back and forth."""
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
            lease, self._lease = self._lease, None
        if lease is not None:
            lease.close()
        return True

    # -- finding work ---------------------------------------------------------------------------------

    def _node_entities(self) -> tuple:
        """``(entities, timers, queues)`` of this executor's nodes (rebuilt only when a node's entities changed).

        Each node keeps its entities in one tuple (``node._work``), replaced when they change; the list
        of those tuples is compared with the cached one element by element (identity first, in C).
        ``queues[i]`` is entity ``i``'s ``_ready_queue`` (subscriptions, services: the deque whose
        contents make it ready; clients: an empty tuple), else None: an empty one is skipped without
        calling ``_ready``, which keeps the scan cheap on nodes with many idle services.
        """
        works = [node._work for node in self._nodes]  # a list read without the lock: a stale view is harmless
        cache = self._entity_cache
        if works != cache[0]:
            with self._nodes_lock:
                works = [node._work for node in self._nodes]
            entities = [entity for work in works for entity in work]
            timers = [entity for entity in entities if hasattr(entity, "_deadline")]
            queues = [getattr(entity, "_ready_queue", None) for entity in entities]
            cache = self._entity_cache = (works, entities, timers, queues)
        return cache[1], cache[2], cache[3]

    def _entities(self) -> list:
        entities = self._node_entities()[0]
        if self._tasks:
            entities = list(entities)
            with self._tasks_lock:
                self._tasks = [t for t in self._tasks if not t.task.done() and not t.task._claimed]
                entities.extend(self._tasks)
        return entities

    def _take_ready(self):
        """``(entity, work, group)`` of one ready callback whose group may run now, or None."""
        with self._take_lock:
            entities, _timers, queues = self._node_entities()
            if self._tasks:
                entities = self._entities()
                queues = None
            count = len(entities)
            if not count:
                return None
            now = time.monotonic()
            start = self._round_robin % count
            for index in range(start, start + count):
                index %= count
                if queues is not None:
                    queue = queues[index]
                    if queue is not None and not queue:
                        continue  # nothing queued: not ready
                entity = entities[index]
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
                self._round_robin = (index + 1) % count
                return entity, work, group
        return None

    def _next_deadline(self) -> float | None:
        deadline = None
        for timer in self._node_entities()[1]:
            value = timer._deadline()
            if value is not None and (deadline is None or value < deadline):
                deadline = value
        return deadline

    def _run(self, entity, work, group) -> None:
        try:
            work()
        except Exception as exc:  # any exception: a callback's failure must not kill the node
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

    def _current_lease(self):
        """This executor's lease with its context's runtime (None before the runtime exists)."""
        runtime = self._context._runtime_instance
        if runtime is None or self._is_shutdown:
            return None
        lease = self._lease
        if lease is not None and lease.runtime is runtime:
            return lease
        if lease is None or lease.runtime is not runtime:
            with self._nodes_lock:
                lease = self._lease
                if (lease is None or lease.runtime is not runtime) and not self._is_shutdown:
                    lease = self._lease = runtime.lease_for(self)
        return lease

    def _poll(self, lease, generation: int, wait: float) -> bool:
        """Wait up to ``wait`` s on the lent sockets and the wake pipe, receiving what arrives; False when
        the sockets are not lent to this executor now (then nothing happened).

        Every socket is drained completely (so a backlog reaches the subscriptions' queues, which drop
        their oldest messages), except after a poll that waited for data: then one message per socket
        is taken and the next poll finds out whether more came. While callbacks keep the executor busy
        it still drains completely every :data:`_PUMP_INTERVAL_S`.
        """
        poller = lease.begin_poll()
        if poller is None:
            return False
        received = 0
        try:
            started = time.monotonic()
            try:
                ready = self._wake.wait(generation, wait, poller)
            except zmq.ZMQError:
                if self._context.ok() and not lease.closed:
                    raise
                ready = None  # the context shut down under us (a signal handler in this thread)
            if ready is not None:
                now = time.monotonic()
                if not ready:
                    self._last_poll = now  # nothing was waiting
                elif wait <= 0 or now - started < _NO_WAIT_S or now - self._last_poll > _PUMP_INTERVAL_S:
                    received = lease.drain(ready)
                    self._last_poll = now
                else:
                    received = lease.drain(ready, 1)
        finally:
            lease.end_poll(received > 0)
        return True

    def _wait_for_work(self, timeout_sec):
        """Wait until work is taken (returned) or the timeout passes (None)."""
        deadline = None if timeout_sec is None or timeout_sec < 0 else time.monotonic() + timeout_sec
        while True:
            if self._is_shutdown or not self._context.ok():
                return None
            generation = self._wake._generation
            lease = self._current_lease()
            if lease is not None:
                state = lease.state
                if state == BUSY and time.monotonic() - self._last_poll > _PUMP_INTERVAL_S:
                    self._poll(lease, self._wake._generation, 0.0)  # busy with callbacks: take in what arrived
                elif state == IO and not lease.wanted:
                    # taken back during a long callback: ask for the sockets again now, not only once the queue is
                    # empty, so what arrives next is received here in batches instead of one I/O-thread wake-up a
                    # message (docs/graph.md, "Socket leases")
                    lease.request()
            found = self._take_ready()
            if found is not None:
                return found
            now = time.monotonic()
            wait = _MAX_WAIT_S
            if deadline is not None:
                if now >= deadline:
                    return None
                wait = min(wait, deadline - now)
            timer_deadline = self._next_deadline() if self._entity_cache[2] else None  # no timers: no deadline
            if timer_deadline is not None:
                wait = min(wait, max(0.0, timer_deadline - now))
            if wait > 0:
                if lease is not None and self._poll(lease, generation, wait):
                    continue
                if lease is not None:
                    lease.request()  # the I/O thread lends the sockets and wakes us
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

