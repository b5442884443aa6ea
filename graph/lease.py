"""Socket leases: a waiting executor receives from its nodes' subscription sockets itself.

Passing each message from the runtime's I/O thread to the executor's thread costs a thread wake-up and
a hand-over of the GIL (``docs/benchmarks.md``, "With socket leases", has the measured cost). So while an
executor waits for work, the I/O thread *lends* it the SUB sockets of the subscriptions of its nodes.
The executor's wait is then one ``zmq_poll`` over those sockets and its own wake pipe, and a message is
received, queued, taken and handed to its callback by one thread.

A ZeroMQ socket may only be used by one thread at a time, so a lease is always in one of three states:

=========== ==================================================================================
``IO``      the I/O thread polls and drains the sockets, as for nodes that no executor spins
``BUSY``    lent to the executor, but no thread touches them (the executor runs callbacks)
``POLLING`` exactly one executor thread is inside ``zmq_poll`` on them, or draining them
=========== ==================================================================================

Every change of state happens under the lease's mutex:

- ``IO -> BUSY``: the executor asks (:meth:`SocketLease.request`); the I/O thread takes the sockets
  out of its own poller and grants them.
- ``BUSY <-> POLLING``: the executor's threads, freely (:meth:`SocketLease.begin_poll`,
  :meth:`SocketLease.end_poll`).
- ``BUSY -> IO``: the I/O thread, when the executor has not polled for :data:`TAKEOVER_S` (a long
  callback, or nobody spins): the sockets are drained at once again, so a slow callback still makes its
  subscription's queue drop the *oldest* messages instead of letting ZeroMQ's pipe fill up and drop
  the newest. Also when a lent socket must be connected, disconnected or closed, or the set of lent
  sockets must change (a node or subscription added, a node moved to another executor, the executor
  shut down): :meth:`SocketLease.invalidate` stops a polling executor first. A node merely removed
  from the executor stays in the lease until one of these happens; what the executor receives for it
  meanwhile wakes the node's new executor, if any.

The I/O thread does not watch a lease that is idle in ``POLLING``: the executor wakes it (one pipe
write) when a poll received messages and the I/O thread sleeps for longer than :data:`TAKEOVER_S`.
While messages flow (and for :data:`WATCH_AFTER_TRAFFIC_S` after), the I/O thread therefore wakes every
:data:`TAKEOVER_S` to watch for a long callback, and not at all otherwise.
"""

from __future__ import annotations

import threading
import time
import weakref

import zmq

__all__ = ["BUSY", "DRAIN_BATCH", "IO", "POLLING", "TAKEOVER_S", "SocketLease", "drain_socket", "receive_frames"]

IO, BUSY, POLLING = "io", "busy", "polling"

#: Seconds an executor may hold its lent sockets without polling them before the I/O thread takes them back.
#: Also how often the I/O thread wakes to watch a lease while messages flow, so a longer period costs less CPU
#: a scan (docs/benchmarks.md, Run 9, compares 10 ms with 25 ms).
TAKEOVER_S = 0.025
#: Seconds after the last poll that received messages during which the I/O thread watches the lease every TAKEOVER_S.
WATCH_AFTER_TRAFFIC_S = 1.0
#: Messages received from one socket in one go before the other sockets get their turn.
DRAIN_BATCH = 1000
# pyzmq's flags as plain ints: ``int & zmq.POLLIN`` goes through the enum module's ``__rand__`` (benchmarks, Run 14)
_EVENTS = int(zmq.EVENTS)
_POLLIN = int(zmq.POLLIN)
_NOBLOCK = int(zmq.NOBLOCK)


def receive_frames(sock) -> list:
    """One waiting multipart message as a list of ``zmq.Frame`` (no copy); raises ``zmq.Again`` when none waits.

    Cheaper than ``recv_multipart(copy=False)``, which asks the socket for RCVMORE after every part:
    here each frame says whether another one follows (the parts of a message arrive together).
    """
    frame = sock.recv(_NOBLOCK, copy=False)
    frames = [frame]
    while frame.more:
        frame = sock.recv(_NOBLOCK, copy=False)
        frames.append(frame)
    return frames


def drain_socket(sock, on_message, limit: int = DRAIN_BATCH) -> int:
    """Receive up to ``limit`` waiting multipart messages from ``sock`` without blocking.

    Call it when a poll found ``sock`` readable. ``on_message(frames)`` is called with each message's
    ``zmq.Frame`` list. Returns how many of the calls returned a true value (messages queued for an
    executor).
    """
    queued = 0
    for _ in range(limit):
        try:
            frames = receive_frames(sock)
        except zmq.Again:
            break
        if on_message(frames):
            queued += 1
        if limit == 1 or not sock.getsockopt(_EVENTS) & _POLLIN:
            break
    return queued


class SocketLease:
    """The subscription sockets of one executor's nodes, lent by one runtime's I/O thread.

    Parameters
    ----------
    executor : Executor
        Held weakly; a lease of a garbage-collected executor is taken back and dropped.
    runtime : GraphRuntime
        The runtime whose I/O thread owns the sockets.
    """

    def __init__(self, executor, runtime) -> None:
        self._executor_ref = weakref.ref(executor)
        self.wake_signal = executor._wake
        self.runtime = runtime
        self.mutex = threading.Lock()
        self.state = IO
        self.subscriptions: dict = {}  # socket -> Subscription, fixed while lent (I/O thread sets it)
        self.poller = None             # zmq.Poller over those sockets and the executor's wake pipe
        self.wanted = False            # the executor asked for the sockets
        self.revoke = False            # the I/O thread wants them back (the set must change)
        self.closed = False            # the executor is shut down: never lend again
        self.busy_since = 0.0          # monotonic time of the last BUSY transition
        self.traffic_at = -1e9         # monotonic time of the last poll that received a message
        self.poll_thread = None        # ident of the thread in POLLING

    @property
    def executor(self):
        return self._executor_ref()

    # -- executor side ------------------------------------------------------------------------------

    def request(self) -> None:
        """Ask the I/O thread for the sockets (when they are with it); cheap when already asked."""
        with self.mutex:
            if self.state != IO or self.wanted or self.closed:
                return
            self.wanted = True
        self.runtime.wake()

    def begin_poll(self):
        """``BUSY -> POLLING`` for the calling thread; returns the poller, or None (not lent to us now)."""
        with self.mutex:
            if self.state != BUSY or self.revoke or self.closed:
                return None
            self.state = POLLING
            self.poll_thread = threading.get_ident()
            return self.poller

    def drain(self, ready, limit: int = DRAIN_BATCH) -> int:
        """Receive what the ready sockets of a ``poller.poll`` hold (only while POLLING, in that thread).

        ``limit=1`` receives one message per socket: the next poll sees whether more are waiting, so
        this saves asking the socket (one system call) when one message came to an idle executor.
        """
        queued = 0
        subscriptions = self.subscriptions
        for sock, _event in ready:
            subscription = subscriptions.get(sock)
            if subscription is not None and subscription._socket is sock:
                count = drain_socket(sock, subscription._on_message, limit)
                if count:
                    queued += count
                    node = subscription._node
                    if node._executor_ref != self._executor_ref:  # the node left this executor meanwhile
                        node._notify_executor()
        return queued

    def covers(self, node) -> bool:
        """Whether every open subscription socket of ``node`` is lent through this lease now."""
        subscriptions = self.subscriptions
        return all(sub._socket is None or sub._socket in subscriptions for sub in list(node._subscriptions))

    def end_poll(self, received: bool) -> None:
        """``POLLING -> BUSY``. When the poll ``received`` messages (callbacks follow) and the I/O thread
        sleeps for longer than TAKEOVER_S, wake it so it watches for a long callback."""
        now = time.monotonic()
        with self.mutex:
            self.state = BUSY
            self.poll_thread = None
            self.busy_since = now
            if received:
                self.traffic_at = now
        if received and self.runtime.sleeping_until > now + TAKEOVER_S:
            self.runtime.wake()

    def invalidate(self) -> None:
        """Ask for the sockets back (the set of lent sockets must change); any thread."""
        with self.mutex:
            if self.state == IO:
                return
            self.revoke = True
        self.wake_signal.notify()
        self.runtime.wake()

    def close(self) -> None:
        """The executor is shut down: take the sockets back and never lend them again; any thread."""
        with self.mutex:
            self.closed = True
            self.wanted = False
            self.revoke = self.state != IO
        self.wake_signal.notify()
        self.runtime.wake()

    # -- I/O thread side ----------------------------------------------------------------------------

    def grant(self, subscriptions: dict, poller, now: float) -> bool:
        """``IO -> BUSY`` with these sockets (already out of the I/O thread's poller); False if no longer wanted."""
        with self.mutex:
            if self.state != IO or not self.wanted or self.closed:
                return False
            self.subscriptions = subscriptions
            self.poller = poller
            self.state = BUSY
            self.busy_since = now
            self.wanted = False
            self.revoke = False
        self.wake_signal.notify()
        return True

    def take_back(self, now: float, *, force: bool = False) -> dict | None:
        """``BUSY -> IO`` when the executor held the sockets unpolled for TAKEOVER_S, or revoke/close asked
        for it (``force``: in any case unless POLLING). Returns the sockets now back with the I/O thread,
        or None when they stay lent."""
        with self.mutex:
            if self.state != BUSY:
                return None
            if not (force or self.revoke or self.closed or now - self.busy_since >= TAKEOVER_S):
                return None
            subscriptions, self.subscriptions = self.subscriptions, {}
            self.poller = None
            self.state = IO
            self.revoke = False
        if not self.closed:
            self.wake_signal.notify()  # a waiting executor asks again
        return subscriptions

    def watch_until(self, now: float) -> float | None:
        """When the I/O thread must look at this lease again (None: only when woken)."""
        with self.mutex:
            state, busy_since, revoke = self.state, self.busy_since, self.revoke or self.closed
            traffic_at = self.traffic_at
        if state == BUSY:
            return now if revoke else busy_since + TAKEOVER_S
        if state == POLLING:
            if revoke:
                return now + 0.001
            if now - traffic_at < WATCH_AFTER_TRAFFIC_S:
                return now + TAKEOVER_S
        return None

    def __repr__(self):
        return f"<SocketLease {self.state} {len(self.subscriptions)} socket(s)>"
