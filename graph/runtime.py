"""The per-context runtime: ZeroMQ context, discovery and the one I/O thread that moves messages.

The I/O thread owns every receiving socket (SUB, the nodes' service ROUTERs, client DEALERs) and:

- drains them as soon as data arrives into the subscriptions' and services' queues, then wakes the
  executors of the nodes concerned (callbacks never run on this thread);
- lends the SUB sockets of a waiting executor's nodes to that executor, which then receives from them
  itself, and takes them back when the executor does not poll them for a while
  (:mod:`dptpu.graph.lease`);
- sends service responses and client requests handed to it by other threads;
- lets each TRANSIENT_LOCAL publisher handle its subscribe events (late-joiner replays) every 25 ms for
  :data:`EVENTS_HOT_S` after the graph changed, every 250 ms otherwise (a publish handles them at once), and
  every publisher once a second (subscriber counts; ``get_subscription_count`` also does it at once);
- every :data:`~dptpu.graph.discovery.SCAN_INTERVAL_S` re-reads the discovery folder, writes this
  process's announcements, and connects or disconnects subscriptions and clients to match the graph
  (immediately, too, when a local entity is created or destroyed);
- once a second rewrites announcements whose counters changed.

Publishers send from the caller's thread (their socket is guarded by a lock), so publishing costs no
thread hop. Any error inside the loop is logged and the loop goes on.
"""

from __future__ import annotations

import hashlib
import math
import os
import queue
import tempfile
import threading
import time
from typing import TYPE_CHECKING

import zmq

from .discovery import (
    FORMAT,
    SCAN_INTERVAL_S,
    DirectoryScanner,
    announcement_file_name,
    base_directory,
    domain_directory,
    ensure_private_directory,
    host_identity,
    process_start_ticks,
    remove_announcement,
    write_announcement,
)
from .endpoint_matching import index_endpoints, wanted_publishers, wanted_servers
from .lease import IO, POLLING, SocketLease, drain_socket
from .logging import get_logger
from .peers import PeerExchange, peers_from_environment
from .services import ServiceHost
from .shared_memory import sweep_mappings
from .transport import MAX_IPC_PATH_BYTES, TransportConfig, connect, remove_ipc_file

if TYPE_CHECKING:  # node imports the runtime (through context): Node is named for the type checker only
    from .node import Node

__all__ = ["GraphRuntime", "EVENTS_HOT_S", "EVENTS_IDLE_INTERVAL_S", "EVENTS_INTERVAL_S", "STATS_INTERVAL_S"]

#: Seconds between two passes over the TRANSIENT_LOCAL publishers' subscribe events (late-joiner replays) for
#: :data:`EVENTS_HOT_S` after the graph changed (a newcomer connects within a few discovery scans of announcing
#: itself), and :data:`EVENTS_IDLE_INTERVAL_S` otherwise: 40 passes a second cost a process ~10 ms of CPU a second
#: (docs/benchmarks.md, Run 17).
EVENTS_INTERVAL_S = 0.025
EVENTS_IDLE_INTERVAL_S = 0.25
EVENTS_HOT_S = 5.0
#: Seconds between two refreshes of the counters in the announcements (and of all publishers' subscriber counts).
STATS_INTERVAL_S = 1.0
#: Longest wait of the I/O thread while it has something to retry (a client request, a lease to take back).
_RETRY_S = 0.005


class GraphRuntime:
    """Everything a context needs to take part in a domain (created with the context's first node)."""

    def __init__(self, domain_id: int, *, peers=None):
        self.domain_id = domain_id
        self.logger = get_logger("dptpu.graph")
        peer_config = peers if peers is not None else peers_from_environment()
        ensure_private_directory(base_directory())  # the base too: nobody else may swap what is inside
        self.directory = ensure_private_directory(domain_directory(domain_id))
        self.transport = TransportConfig.from_environment(want_tcp=peer_config is not None, key_dir=self.directory)
        if self.transport.insecure_tcp:
            self.logger.warning(f"tcp endpoints on {self.transport.tcp_interface} without CurveZMQ (DPTPU_CURVE=off): "
                                "anyone who can reach them may read every topic, publish and call services")
        self.ipc_dir = self._ipc_directory()
        self.host, self.boot_id = host_identity()
        self.pid = os.getpid()
        self.pid_start = process_start_ticks(self.pid)
        self.zmq_context = zmq.Context(io_threads=1)
        self._authenticator = None
        if self.transport.curve is not None:
            from zmq.auth.thread import ThreadAuthenticator  # deferred: only with CURVE; brings asyncio in

            self._authenticator = ThreadAuthenticator(self.zmq_context)
            self._authenticator.start()
            self._authenticator.configure_curve(domain="*", location=str(self.transport.curve.authorized_keys_dir))
        self._scanner = DirectoryScanner(self.directory, host=self.host, boot_id=self.boot_id)
        self._lock = threading.RLock()
        self._nodes: dict[str, Node] = {}
        self._files: dict[str, str] = {}
        self._written_stats: dict[str, object] = {}
        self._dirty: set[str] = set()
        self._publishers: set = set()
        self._subscriptions: set = set()
        self._clients: set = set()
        self._hosts: dict[str, ServiceHost] = {}
        self._pending_clients: set = set()
        self._handlers: dict = {}       # socket -> handler, for the sockets the I/O thread polls now
        self._lent: dict = {}           # socket -> SocketLease, for the SUB sockets lent to an executor
        self._leases: set = set()
        self._deferred: list = []       # commands waiting until a lease gave its sockets back
        self.sleeping_until = float("inf")  # monotonic time the I/O thread sleeps until (inf: awake)
        self._commands: queue.SimpleQueue = queue.SimpleQueue()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._poller = zmq.Poller()
        self._poller.register(self._wake_r, zmq.POLLIN)
        self._rematch = True
        self._running = True
        self.entries: list[dict] = []  # the whole graph (others' and ours), refreshed by the I/O thread
        self._peers = PeerExchange(self, peer_config) if peer_config is not None else None
        self._thread = threading.Thread(target=self._run, name=f"dptpu-graph-io-{domain_id}", daemon=True)
        self._thread.start()

    def _ipc_directory(self):
        folder = self.directory / "ep"
        if len(str(folder / ("x" * 16)).encode()) > MAX_IPC_PATH_BYTES:
            digest = hashlib.sha1(str(self.directory).encode()).hexdigest()[:12]
            folder = type(self.directory)(tempfile.gettempdir()) / f"dptpu-{os.getuid()}-ep-{digest}"
        return ensure_private_directory(folder)

    # -- thread-safe API ----------------------------------------------------------------------------

    def wake(self) -> None:
        try:
            os.write(self._wake_w, b"\0")
        except (BlockingIOError, OSError):
            pass  # already awake (pipe full) or closed

    def call_soon(self, function) -> None:
        """Run ``function()`` on the I/O thread."""
        self._commands.put(function)
        self.wake()

    def add_node(self, node) -> None:
        with self._lock:
            self._nodes[node._gid] = node
            self._dirty.add(node._gid)
            self._rematch = True
        self.wake()

    def remove_node(self, node) -> None:
        with self._lock:
            self._nodes.pop(node._gid, None)
            self._dirty.discard(node._gid)
            name = self._files.pop(node._gid, None)
            if name:
                remove_announcement(self.directory, name)
            self._rematch = True
        self.call_soon(lambda: self._close_host(node._gid))

    def mark_dirty(self, node) -> None:
        with self._lock:
            if node._gid in self._nodes:
                self._dirty.add(node._gid)
            self._rematch = True
        self.wake()

    def add_publisher(self, publisher) -> None:
        with self._lock:
            self._publishers.add(publisher)

    def remove_publisher(self, publisher) -> None:
        with self._lock:
            self._publishers.discard(publisher)
        publisher._close()

    def add_subscription(self, subscription) -> None:
        self.call_soon(lambda: self._open(subscription, self._subscriptions,
                                          lambda: subscription._open(self.zmq_context, self.transport)))

    def remove_subscription(self, subscription) -> None:
        subscription._destroyed = True
        self.call_soon(lambda: self._close(subscription, self._subscriptions))

    def add_client(self, client) -> None:
        self.call_soon(lambda: self._open(client, self._clients, lambda: client._open(self.zmq_context,
                                                                                       self.transport)))

    def remove_client(self, client) -> None:
        client._destroyed = True
        self.call_soon(lambda: self._close(client, self._clients))

    def add_service(self, node, service) -> None:
        def add():
            host = self._host(node)
            host.services[service.srv_name] = service
            self.mark_dirty(node)
        self.call_soon(add)

    def remove_service(self, node, service) -> None:
        service._destroyed = True

        def remove():
            host = self._hosts.get(node._gid)
            if host is not None and host.services.get(service.srv_name) is service:
                del host.services[service.srv_name]
        self.call_soon(remove)

    def send_service_response(self, node, identity: bytes, frames: list) -> None:
        def send():
            host = self._hosts.get(node._gid)
            if host is not None:
                host.send(identity, frames)
        self.call_soon(send)

    def flush_client(self, client) -> None:
        self.call_soon(lambda: self._flush_client(client))

    def service_transient_local_publishers(self) -> None:
        """Let every TRANSIENT_LOCAL publisher replay its history to new subscribers now (any thread)."""
        with self._lock:
            publishers = [p for p in self._publishers if p._history is not None]
        for publisher in publishers:
            publisher._service_events()

    def lease_for(self, executor) -> SocketLease:
        """A new lease through which ``executor`` may receive from its nodes' subscription sockets."""
        lease = SocketLease(executor, self)
        with self._lock:
            self._leases.add(lease)
        return lease

    def service_endpoints(self, node) -> list[str]:
        host = self._hosts.get(node._gid)
        return list(host.endpoints) if host is not None else []

    def stop(self) -> None:
        """Stop the I/O thread, remove this process's announcements, close every socket."""
        with self._lock:
            for name in list(self._files.values()):
                remove_announcement(self.directory, name)
            self._files.clear()
            self._nodes.clear()
            publishers = list(self._publishers)
            self._publishers.clear()
            leases = list(self._leases)
        for lease in leases:
            lease.close()  # no executor polls a socket from now on ...
        deadline = time.monotonic() + 2.0
        me = threading.get_ident()
        while time.monotonic() < deadline and any(lease.state == POLLING and lease.poll_thread != me
                                                  for lease in leases):
            time.sleep(0.001)  # ... once the ones inside zmq_poll returned (close() woke them)
        self._running = False
        self.wake()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        for publisher in publishers:
            publisher._close()
        for gid in list(self._hosts):
            self._close_host(gid)
        if self._peers is not None:
            self._peers.close()
        if self._authenticator is not None:
            self._authenticator.stop()
        self.zmq_context.destroy(linger=0)
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass

    # -- I/O thread ---------------------------------------------------------------------------------

    def _run(self) -> None:
        next_scan = next_events = next_stats = 0.0
        events_hot_until = float("inf")  # fast event passes until then (from start-up until the first match)
        while self._running:
            self.sleeping_until = float("inf")  # an executor going BUSY from now on wakes this thread
            now = time.monotonic()
            wake_at = min(next_scan, next_stats)
            if any(publisher._history is not None for publisher in list(self._publishers)):
                wake_at = min(wake_at, next_events)  # TRANSIENT_LOCAL replays
            if self._pending_clients or self._rematch or self._dirty or self._deferred:
                wake_at = min(wake_at, now + _RETRY_S)
            for lease in list(self._leases):
                look = lease.watch_until(now)
                if look is not None:
                    wake_at = min(wake_at, look)
            self.sleeping_until = wake_at
            try:
                # whole ms, rounded up: zmq_poll truncates, and waking early would spin until the deadline
                ready = self._poller.poll(math.ceil(max(0.0, wake_at - now) * 1000.0))
            except zmq.ZMQError:
                if not self._running:
                    break
                raise
            self.sleeping_until = float("inf")
            woken = False
            if ready:
                notify: set[Node] = set()  # nodes with new messages, whose executors to wake
                for sock, _ in ready:
                    if sock == self._wake_r:
                        woken = True
                        continue
                    handler = self._handlers.get(sock)
                    if handler is not None:
                        self._guard(self._drain, sock, handler, notify)
                for node in notify:  # first, so the executors start while the rest of the loop runs
                    node._notify_executor()
            if woken or not self._commands.empty():
                self._guard(self._run_commands)
            for client in list(self._pending_clients):
                self._guard(self._flush_client, client)
            now = time.monotonic()
            if self._leases:
                self._guard(self._reclaim_leases, now)
            if self._deferred:
                self._guard(self._run_deferred)
            if now >= next_events:
                next_events = now + (EVENTS_INTERVAL_S if now < events_hot_until else EVENTS_IDLE_INTERVAL_S)
                for publisher in list(self._publishers):
                    if publisher._history is not None:  # TRANSIENT_LOCAL: replay to late joiners soon
                        self._guard(publisher._service_events)
            if now >= next_scan or self._rematch or self._dirty:
                if now >= next_scan:
                    next_scan = now + SCAN_INTERVAL_S
                    self._guard(self._scan, now)
                self._guard(self._write_announcements)
                if self._rematch:
                    self._rematch = False
                    self._guard(self._match)
                    # the graph changed: a newcomer may connect to a TRANSIENT_LOCAL publisher here soon
                    events_hot_until = now + EVENTS_HOT_S
                    next_events = min(next_events, now + EVENTS_INTERVAL_S)
            if now >= next_stats:
                next_stats = now + STATS_INTERVAL_S
                self._guard(self._refresh_stats)
                if self._peers is not None:
                    self._guard(self._peers.step)
            if self._leases and not self._rematch and not self._deferred:
                # last: sockets go out only once connects, disconnects and closes are done with them
                self._guard(self._grant_leases, now)

    def _guard(self, function, *args) -> None:
        """``function(*args)``, logging (not raising) whatever it raises."""
        try:
            function(*args)
        except Exception as exc:  # any exception: the I/O thread must survive anything
            if self._running:
                self.logger.error(f"graph I/O thread: {type(exc).__name__}: {exc}", exc_info=True,
                                  throttle_duration_sec=1.0)

    def _run_commands(self) -> None:
        try:
            while os.read(self._wake_r, 4096):
                pass
        except (BlockingIOError, OSError):
            pass
        while True:
            try:
                command = self._commands.get_nowait()
            except queue.Empty:
                return
            self._guard(command)

    def _drain(self, sock, handler, notify: set) -> None:
        def on_message(frames):
            node = handler(frames)
            if node is not None:
                notify.add(node)
        drain_socket(sock, on_message)

    @staticmethod
    def _handler_for(entity):
        if hasattr(entity, "_flush"):
            return lambda frames, e=entity: e._on_message(frames)  # clients notify nobody
        return lambda frames, e=entity: e._node if e._on_message(frames) else None

    def _open(self, entity, registry: set, opener) -> None:
        if entity._destroyed:
            return
        sock = opener()
        registry.add(entity)
        self._handlers[sock] = self._handler_for(entity)
        self._poller.register(sock, zmq.POLLIN)
        self._rematch = True
        if not hasattr(entity, "_flush"):  # a new subscription: its executor's lease must include it
            lease = self._lease_of(entity._node)
            if lease is not None:
                lease.invalidate()

    def _close(self, entity, registry: set) -> None:
        sock = entity._socket
        lease = self._lent.get(sock) if sock is not None else None
        if lease is not None:  # lent to an executor: close it once the lease gave it back
            lease.invalidate()
            self._deferred.append(lambda: self._close(entity, registry))
            return
        registry.discard(entity)
        self._pending_clients.discard(entity)
        if sock is not None:
            self._handlers.pop(sock, None)
            try:
                self._poller.unregister(sock)
            except KeyError:
                pass
            sock.close(linger=0)
            entity._socket = None
        entity._connected.clear()

    def _run_deferred(self) -> None:
        deferred, self._deferred = self._deferred, []
        for command in deferred:
            self._guard(command)  # may defer itself again

    # -- socket leases (see dptpu.graph.lease) ------------------------------------------------------

    def _lease_of(self, node):
        """The lease of ``node``'s executor with this runtime, or None."""
        executor = node.executor
        lease = getattr(executor, "_lease", None) if executor is not None else None
        return lease if lease is not None and lease.runtime is self else None

    def _reclaim_leases(self, now: float) -> None:
        """Take back the sockets of executors that did not poll them for TAKEOVER_S, or must give them back."""
        for lease in list(self._leases):
            executor = lease.executor
            back = lease.take_back(now, force=executor is None or lease.closed)
            if back is not None:
                self._own_again(back, lease)
            if (executor is None or lease.closed) and lease.state == IO:
                with self._lock:
                    self._leases.discard(lease)

    def _grant_leases(self, now: float) -> None:
        for lease in list(self._leases):
            if lease.state == IO and lease.wanted and not lease.closed:
                executor = lease.executor
                if executor is not None:
                    self._grant(lease, executor, now)

    def _grant(self, lease, executor, now: float) -> None:
        subscriptions = {}
        for sub in list(self._subscriptions):
            sock = sub._socket
            if sock is None or sub._destroyed or sub._node.executor is not executor:
                continue
            other = self._lent.get(sock)
            if other is not None:  # still lent to the node's previous executor: it gives it back, then we refresh
                other.invalidate()
                continue
            subscriptions[sock] = sub
        poller = zmq.Poller()
        poller.register(executor._wake.fd, zmq.POLLIN)
        for sock in subscriptions:
            self._handlers.pop(sock, None)
            try:
                self._poller.unregister(sock)
            except KeyError:
                pass
            poller.register(sock, zmq.POLLIN)
            self._lent[sock] = lease
        if not lease.grant(subscriptions, poller, now):
            self._own_again(subscriptions, lease)

    def _own_again(self, subscriptions: dict, lease) -> None:
        """Poll these sockets on the I/O thread again (they came back from ``lease``)."""
        for sock, sub in subscriptions.items():
            if self._lent.get(sock) is lease:
                del self._lent[sock]
            if sub._socket is not sock:
                continue
            self._handlers[sock] = self._handler_for(sub)
            self._poller.register(sock, zmq.POLLIN)
            if sub._queue:
                sub._node._notify_executor()  # it may belong to another executor by now
            other = self._lease_of(sub._node)
            if other is not None and other is not lease:
                other.invalidate()  # the node moved to another executor: that one's lease must include it

    def _host(self, node):
        host = self._hosts.get(node._gid)
        if host is None:
            host = ServiceHost(node)
            sock = host._open(self)
            self._hosts[node._gid] = host
            self._handlers[sock] = lambda frames, h=host: h._node if h._on_message(frames) else None
            self._poller.register(sock, zmq.POLLIN)
            self.mark_dirty(node)
        return host

    def _close_host(self, node_gid: str) -> None:
        host = self._hosts.pop(node_gid, None)
        if host is not None and host._socket is not None:
            self._handlers.pop(host._socket, None)
            try:
                self._poller.unregister(host._socket)
            except KeyError:
                pass
            host._socket.close(linger=0)
            host._socket = None
            for endpoint in host.endpoints:
                remove_ipc_file(endpoint)

    def _flush_client(self, client) -> None:
        if client._flush():
            self._pending_clients.add(client)
        else:
            self._pending_clients.discard(client)

    # -- discovery ----------------------------------------------------------------------------------

    def _scan(self, now: float) -> None:
        if self._scanner.scan(now):
            if self._scanner.topology_changed:
                self._rematch = True
            elif not self._rematch:
                self.entries = self._graph_entries()  # only counters changed: a fresh snapshot, no matching
        if self._peers is not None and self._peers.changed():
            self._rematch = True

    def _own_entry(self, node) -> dict:
        entry = node._announcement()
        host = self._hosts.get(node._gid)
        # announce a service only once the node's ROUTER routes requests to it
        entry["services"] = [s for s in entry["services"] if host is not None and s["name"] in host.services]
        entry.update({"format": FORMAT, "pid": self.pid, "pid_start": self.pid_start, "host": self.host,
                      "boot_id": self.boot_id, "domain_id": self.domain_id,
                      "service_endpoints": self.service_endpoints(node),
                      "curve_public_key": self.transport.curve.public.decode("ascii") if self.transport.curve
                      else None, "updated": time.time()})
        return entry

    def _write_announcements(self) -> None:
        with self._lock:
            dirty, self._dirty = self._dirty, set()
            for gid in dirty:
                node = self._nodes.get(gid)
                if node is None:
                    continue
                name = self._files.get(gid) or announcement_file_name(self.pid, gid)
                self._scanner.own_files.add(name)
                entry = self._own_entry(node)
                write_announcement(self.directory, name, entry)
                self._files[gid] = name
                self._written_stats[gid] = node._stats_signature()

    def _refresh_stats(self) -> None:
        for publisher in list(self._publishers):
            self._guard(publisher._service_events)  # subscriber counts
        sweep_mappings()  # unmap other processes' shared-memory segments no message here holds any more
        with self._lock:
            for gid, node in list(self._nodes.items()):
                if self._written_stats.get(gid) != node._stats_signature():
                    self._dirty.add(gid)
        self._write_announcements()

    def _graph_entries(self) -> list[dict]:
        """The whole graph: the other processes' announcements (and peers'), then this process's own."""
        with self._lock:
            own = [self._own_entry(node) for node in self._nodes.values()]
        foreign = list(self._scanner.entries)
        if self._peers is not None:
            foreign.extend(self._peers.entries())
        return foreign + own

    def _match(self) -> None:
        entries = self._graph_entries()
        self.entries = entries
        publishers, servers = index_endpoints(entries)
        for sub in list(self._subscriptions):
            self._guard(self._match_subscription, sub, publishers.get(sub.topic_name, []))
        for client in list(self._clients):
            self._guard(self._match_client, client, servers.get(client.srv_name, []))

    def _same_host(self, entry: dict) -> bool:
        return entry.get("host") == self.host and entry.get("boot_id") == self.boot_id

    def _match_subscription(self, sub, candidates) -> None:
        if sub._socket is None or sub._destroyed:
            return
        wanted = wanted_publishers(sub, candidates, same_host=self._same_host, transport=self.transport)
        if set(wanted) != set(sub._connected):
            lease = self._lent.get(sub._socket)
            if lease is not None:  # lent to an executor: (dis)connect once it is back
                lease.invalidate()
                self._rematch = True
                return
        for endpoint in set(sub._connected) - set(wanted):
            gid = sub._connected.pop(endpoint)
            try:
                sub._socket.disconnect(endpoint)
            except zmq.ZMQError:
                pass
            try:
                sub._forget_publisher(bytes.fromhex(gid))
            except ValueError:
                pass
        for endpoint, (gid, key) in wanted.items():
            if endpoint not in sub._connected:
                connect(sub._socket, endpoint, self.transport, key)
                sub._connected[endpoint] = gid

    def _match_client(self, client, candidates) -> None:
        if client._socket is None:
            return
        wanted = wanted_servers(client, candidates, same_host=self._same_host, transport=self.transport)
        for endpoint in set(client._connected) - set(wanted):
            client._connected.pop(endpoint)
            try:
                client._socket.disconnect(endpoint)
            except zmq.ZMQError:
                pass
        for endpoint, (gid, key) in wanted.items():
            if endpoint not in client._connected:
                connect(client._socket, endpoint, self.transport, key)
                client._connected[endpoint] = gid
        if client._outbox:
            self._flush_client(client)
