"""Contexts: ``init``, ``ok``, ``shutdown`` (``rclpy.context`` and the module functions of ``rclpy``).

A context holds the parsed ROS command line (global remappings, parameters, log levels), the domain
id, and, from its first node on, the runtime (ZeroMQ context, discovery, I/O thread). ``shutdown``
destroys its nodes (their announcements disappear at once), stops the runtime and wakes every
executor, whose ``spin`` then returns.

Process exit: ``init`` registers an ``atexit`` hook that shuts down every context still running, and,
when called from the main thread while SIGTERM has its default action, makes SIGTERM raise
``KeyboardInterrupt`` like Ctrl-C, so ``try: spin(node) except KeyboardInterrupt: ...`` cleans up on
both. A process killed with SIGKILL leaves its announcement behind; the others ignore it (dead pid)
and delete it within a second.
"""

from __future__ import annotations

import atexit
import signal
import sys
import threading
import weakref

from .arguments import RosArguments, parse_ros_arguments
from .discovery import resolve_domain_id
from .exceptions import NotInitializedException
from .runtime import GraphRuntime

__all__ = ["Context", "get_default_context", "init", "shutdown", "try_shutdown", "ok"]


class Context:
    """The scope of nodes that share a command line, a domain and a runtime."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._ok = False
        self._initialized = False
        self._arguments = RosArguments()
        self._domain_id: int | None = None
        self._runtime_instance: GraphRuntime | None = None
        self._nodes: weakref.WeakSet = weakref.WeakSet()
        self._executors: weakref.WeakSet = weakref.WeakSet()
        self._shutdown_callbacks: list = []

    def init(self, args=None, *, initialize_logging: bool = True, domain_id=None) -> None:
        """Parse ``args`` (``sys.argv``-like, None = ``sys.argv``; only what follows ``--ros-args`` matters) and start.

        Raises
        ------
        RuntimeError
            When the context is running already (a shut-down context may be initialized again).
        ROSArgumentsError, UnknownROSArgsError
            For a malformed or unknown ROS argument.
        ValueError
            For a domain id outside 0..232.
        """
        with self._lock:
            if self._ok:
                raise RuntimeError("Context.init() must only be called once (shut it down first)")
            self._arguments = parse_ros_arguments(sys.argv if args is None else args)
            self._domain_id = resolve_domain_id(domain_id)
            self._initialized = True
            self._ok = True
        _live_contexts.add(self)

    def ok(self) -> bool:
        return self._ok

    def get_domain_id(self) -> int:
        if self._domain_id is None:
            raise NotInitializedException()
        return self._domain_id

    @property
    def domain_id(self) -> int:
        return self.get_domain_id()

    @property
    def arguments(self) -> RosArguments:
        """The parsed ROS arguments given to ``init``."""
        return self._arguments

    def on_shutdown(self, callback) -> None:
        """Call ``callback()`` when the context shuts down."""
        if not callable(callback):
            raise ValueError(f"callback must be callable; got {callback!r}")
        self._shutdown_callbacks.append(callback)

    def shutdown(self) -> None:
        """Destroy this context's nodes, stop its runtime, wake its executors.

        Raises
        ------
        RuntimeError
            When the context is not initialized or already shut down (use :meth:`try_shutdown`).
        """
        with self._lock:
            if not self._ok:
                raise RuntimeError("Context.shutdown() called on a context that is not initialized or already "
                                   "shut down")
            self._ok = False
            nodes = list(self._nodes)
            executors = list(self._executors)
        for node in nodes:
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001 -- keep shutting down the rest
                pass
        runtime, self._runtime_instance = self._runtime_instance, None
        if runtime is not None:
            runtime.stop()
        for executor in executors:
            executor.wake()
        callbacks, self._shutdown_callbacks = self._shutdown_callbacks, []
        for callback in callbacks:
            callback()
        _live_contexts.discard(self)

    def try_shutdown(self) -> None:
        """Shut down if still running; do nothing otherwise."""
        if self._ok:
            self.shutdown()

    # -- internal -----------------------------------------------------------------------------------

    def _runtime(self):
        """The runtime, created on first use."""
        with self._lock:
            if not self._ok:
                raise NotInitializedException()
            if self._runtime_instance is None:
                self._runtime_instance = GraphRuntime(self._domain_id)
            return self._runtime_instance

    def _track_node(self, node) -> None:
        self._nodes.add(node)

    def _untrack_node(self, node) -> None:
        self._nodes.discard(node)

    def _track_executor(self, executor) -> None:
        self._executors.add(executor)


_default_context = Context()
_live_contexts: weakref.WeakSet = weakref.WeakSet()
_hooks_installed = False


def get_default_context() -> Context:
    return _default_context


def _shutdown_all_at_exit() -> None:
    for context in list(_live_contexts):
        try:
            context.try_shutdown()
        except Exception:  # noqa: BLE001 -- exiting anyway
            pass


def _sigterm_as_interrupt(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def _install_hooks() -> None:
    global _hooks_installed
    if _hooks_installed:
        return
    _hooks_installed = True
    atexit.register(_shutdown_all_at_exit)
    if threading.current_thread() is threading.main_thread():
        try:
            if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
                signal.signal(signal.SIGTERM, _sigterm_as_interrupt)
        except (ValueError, OSError):
            pass


def init(args=None, *, context=None, domain_id=None) -> None:
    """Initialize ``context`` (default: the default context) with ``args`` (None: ``sys.argv``) and a domain id.

    ``domain_id`` defaults to ``$DPTPU_DOMAIN_ID``, then ``$ROS_DOMAIN_ID``, then 0.
    """
    (context if context is not None else _default_context).init(args, domain_id=domain_id)
    _install_hooks()


def shutdown(*, context=None) -> None:
    """Shut down ``context`` (default: the default context); RuntimeError when it is not running."""
    (context if context is not None else _default_context).shutdown()


def try_shutdown(*, context=None) -> None:
    (context if context is not None else _default_context).try_shutdown()


def ok(*, context=None) -> bool:
    return (context if context is not None else _default_context).ok()
