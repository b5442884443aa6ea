"""Services and clients: request/response over one ROUTER socket per node and one DEALER per client.

A node's services share one ROUTER endpoint (announced as ``service_endpoints``); a request names
its service in the topic frame, so one socket serves ``~/get_parameters``, ``~/set_parameters`` and
the node's own services. A client's DEALER connects to every node that serves its service name with
its type (discovery) and sends each request to one of them (round robin when several serve it).

Frames: request ``[service name, header, *arrays, envelope(REQUEST, id, client gid)]``; response the
same with RESPONSE; when the server's callback raises or the request cannot be decoded the response
is ``[service name, reason, envelope(RESPONSE|ERROR)]`` and the client's future fails with
:class:`~dptpu.graph.exceptions.ServiceCallError` (ROS 2 would leave the call unanswered).

Responses complete futures from the I/O thread, so ``client.call(request)`` works anywhere, even inside
a callback of a single-threaded executor. A request sent to a server that dies before answering is not
answered: use ``call(request, timeout_sec=...)``.
"""

from __future__ import annotations

import threading
import time
import uuid
from collections import deque

import zmq

from ..messages.decoder import decode
from ..messages.encoder import encode
from ..messages.wire_format import DecodeError
from .exceptions import ServiceCallError
from .task import Future
from .transport import (
    FLAG_ERROR,
    FLAG_REQUEST,
    FLAG_RESPONSE,
    EnvelopeError,
    bind_endpoints,
    configure_client,
    configure_server,
    pack_envelope,
    unpack_envelope,
)

__all__ = ["Service", "Client", "ServiceHost", "MAX_QUEUED_REQUESTS"]

#: Requests a service queues while its callback is busy; more are answered with an error.
MAX_QUEUED_REQUESTS = 1000


def _error_frames(name: str, reason: str, seq: int, gid: bytes) -> list:
    return [name.encode("utf-8"), reason.encode("utf-8")[:4000],
            pack_envelope(FLAG_RESPONSE | FLAG_ERROR, seq, time.time_ns(), gid)]


class ServiceHost:
    """The ROUTER socket of one node's services (I/O thread side)."""

    def __init__(self, node) -> None:
        self._node = node
        self.services: dict[str, Service] = {}
        self.endpoints: list[str] = []
        self._socket = None
        self.malformed_count = 0

    def _open(self, runtime) -> zmq.Socket:
        sock = runtime.zmq_context.socket(zmq.ROUTER)
        try:
            sock.setsockopt(zmq.RCVHWM, 1000)
            sock.setsockopt(zmq.SNDHWM, 1000)
            sock.setsockopt(zmq.LINGER, 0)
            configure_server(sock, runtime.transport)
            self.endpoints = bind_endpoints(sock, runtime.transport, runtime.ipc_dir, "s" + self._node._gid[:15])
        except BaseException:
            sock.close(linger=0)
            raise
        self._socket = sock
        return sock

    def _on_message(self, frames) -> bool:
        """Route one request to its service; True when a service got work."""
        if len(frames) < 4:
            self._malformed(f"request of {len(frames)} frame(s)")
            return False
        identity = frames[0].bytes
        try:
            envelope = unpack_envelope(frames[-1])
        except EnvelopeError as exc:
            self._malformed(str(exc))
            return False
        if not envelope.flags & FLAG_REQUEST:
            self._malformed("a message without the REQUEST flag on a service socket")
            return False
        try:
            name = bytes(frames[1].buffer).decode("utf-8")
        except UnicodeDecodeError:
            self._malformed("service name is not UTF-8")
            return False
        service = self.services.get(name)
        if service is None:
            self.send(identity, _error_frames(name, f"node {self._node.get_fully_qualified_name()} has no service "
                                                    f"{name}", envelope.seq, envelope.gid))
            return False
        return service._on_request(identity, frames[1:-1], envelope)

    def send(self, identity: bytes, frames: list) -> None:
        if self._socket is None:
            return
        try:
            self._socket.send_multipart([identity] + list(frames), flags=zmq.NOBLOCK, copy=False)
        except zmq.ZMQError:
            pass  # the client is gone or its pipe is full: the response is dropped

    def _malformed(self, reason: str) -> None:
        self.malformed_count += 1
        self._node.get_logger().warning(f"malformed service request ({self.malformed_count} so far): {reason}",
                                        throttle_duration_sec=1.0)


class Service:
    """Answers requests of one service type (create with ``node.create_service``).

    ``callback(request, response) -> response``: fill in the given empty response and return it.
    """

    def __init__(self, node, srv_type, srv_name: str, callback, qos_profile, callback_group):
        self._node = node
        self.srv_type = srv_type
        self.srv_name = srv_name
        self.callback = callback
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self._requests: deque = deque()
        self._ready_queue = self._requests  # the executor skips this service while it is empty
        self._lock = threading.Lock()
        self.request_count = 0
        self.malformed_count = 0
        self.exception_count = 0
        self._destroyed = False

    @property
    def service_name(self) -> str:
        return self.srv_name

    def destroy(self) -> bool:
        return self._node.destroy_service(self)

    def _on_request(self, identity: bytes, frames, envelope) -> bool:
        with self._lock:
            if len(self._requests) >= MAX_QUEUED_REQUESTS:
                busy = True
            else:
                busy = False
                self._requests.append((identity, frames, envelope))
                self.request_count += 1
        if busy:
            self._respond(identity, _error_frames(self.srv_name, f"service {self.srv_name} is busy "
                                                  f"({MAX_QUEUED_REQUESTS} requests queued)", envelope.seq,
                                                  envelope.gid))
        return not busy

    def _respond(self, identity: bytes, frames: list) -> None:
        self._node.context._runtime().send_service_response(self._node, identity, frames)

    def _ready(self, now: float) -> bool:
        return bool(self._requests) and not self._destroyed

    def _take(self):
        with self._lock:
            if not self._requests or self._destroyed:
                return None
            identity, frames, envelope = self._requests.popleft()
        try:
            _, request = decode(frames, expected_type=self.srv_type.Request)
        except DecodeError as exc:
            self.malformed_count += 1
            self._node.get_logger().warning(f"malformed request to {self.srv_name}: {exc}", throttle_duration_sec=1.0)
            self._respond(identity, _error_frames(self.srv_name, f"server could not decode the request: {exc}",
                                                  envelope.seq, envelope.gid))
            return None
        return lambda: self._handle(identity, request, envelope)

    def _handle(self, identity: bytes, request, envelope) -> None:
        try:
            response = self.callback(request, self.srv_type.Response())
            if not isinstance(response, self.srv_type.Response):
                raise ValueError(f"service callback for {self.srv_name} must return a {self.srv_type.__name__}."
                                 f"Response; got {type(response).__name__}")
            frames = encode(self.srv_name, response)
        except Exception as exc:
            self._respond(identity, _error_frames(self.srv_name, f"{type(exc).__name__}: {exc}", envelope.seq,
                                                  envelope.gid))
            raise
        frames.append(pack_envelope(FLAG_RESPONSE, envelope.seq, time.time_ns(), envelope.gid))
        self._respond(identity, frames)

    def _describe(self) -> str:
        return f"service callback of {self.srv_name}"

    def __repr__(self):
        return f"<Service {self.srv_name} [{self.srv_type.TYPE_NAME}]>"


class Client:
    """Calls one service (create with ``node.create_client``)."""

    def __init__(self, node, srv_type, srv_name: str, qos_profile, callback_group):
        self._node = node
        self.srv_type = srv_type
        self.srv_name = srv_name
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self.gid = uuid.uuid4().bytes
        self._lock = threading.Lock()
        self._next_id = 0
        self._pending: dict[int, Future] = {}
        self._outbox: deque = deque()
        self._socket = None          # I/O thread
        self._connected: dict = {}   # endpoint -> server node gid (I/O thread)
        self.malformed_count = 0
        self._destroyed = False

    @property
    def service_name(self) -> str:
        return self.srv_name

    def call_async(self, request) -> Future:
        """Send ``request``; return a :class:`Future` completed with the response.

        Raises
        ------
        ValueError
            ``request`` is not a ``srv_type.Request`` or has an invalid field.
        """
        if not isinstance(request, self.srv_type.Request):
            raise ValueError(f"client of {self.srv_name} expects a {self.srv_type.__name__}.Request; got "
                             f"{type(request).__name__}")
        frames = encode(self.srv_name, request)
        future = Future(executor=self._node.executor)
        with self._lock:
            if self._destroyed:
                raise RuntimeError(f"client of {self.srv_name} was destroyed")
            self._next_id += 1
            request_id = self._next_id
            self._pending[request_id] = future
            frames.append(pack_envelope(FLAG_REQUEST, request_id, time.time_ns(), self.gid))
            self._outbox.append(frames)
        self._node.context._runtime().flush_client(self)
        return future

    def call(self, request, timeout_sec: float | None = None):
        """Send ``request`` and wait for the response (no spinning needed).

        Raises
        ------
        TimeoutError
            No response within ``timeout_sec``.
        ServiceCallError
            The server answered with an error.
        """
        future = self.call_async(request)
        if not future.wait(timeout_sec):
            self.remove_pending_request(future)
            raise TimeoutError(f"no response from service {self.srv_name} within {timeout_sec} s")
        return future.result()

    def remove_pending_request(self, future: Future) -> None:
        with self._lock:
            for request_id, pending in list(self._pending.items()):  # as rclpy: a few pending requests at most
                if pending is future:
                    del self._pending[request_id]

    def service_is_ready(self) -> bool:
        """True when discovery has connected this client to at least one server."""
        return bool(self._connected)

    def wait_for_service(self, timeout_sec: float | None = None) -> bool:
        """Block until a server is available (True) or ``timeout_sec`` passed (False)."""
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not self.service_is_ready():
            if not self._node.context.ok():
                return False
            if deadline is not None and time.monotonic() >= deadline:
                return False
            time.sleep(0.005)
        return True

    def destroy(self) -> bool:
        return self._node.destroy_client(self)

    # -- I/O thread side ----------------------------------------------------------------------------

    def _open(self, zmq_context, transport) -> zmq.Socket:
        sock = zmq_context.socket(zmq.DEALER)
        sock.setsockopt(zmq.IMMEDIATE, 1)
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.SNDHWM, 1000)
        sock.setsockopt(zmq.RCVHWM, 1000)
        configure_client(sock, transport)
        self._socket = sock
        return sock

    def _flush(self) -> bool:
        """Send queued requests; True when some are still waiting for a connected server."""
        sock = self._socket
        if sock is None:
            return bool(self._outbox)
        while self._outbox:
            frames = self._outbox[0]
            try:
                sock.send_multipart(frames, flags=zmq.NOBLOCK, copy=False)
            except zmq.Again:
                return True
            self._outbox.popleft()
        return False

    def _on_message(self, frames) -> None:
        try:
            envelope = unpack_envelope(frames[-1])
        except (EnvelopeError, IndexError) as exc:
            self.malformed_count += 1
            self._node.get_logger().warning(f"malformed response from {self.srv_name}: {exc}",
                                            throttle_duration_sec=1.0)
            return
        with self._lock:
            future = self._pending.pop(envelope.seq, None)
        if future is None or future.done():
            return  # timed out or cancelled meanwhile
        if envelope.flags & FLAG_ERROR:
            reason = bytes(frames[1].buffer).decode("utf-8", "replace") if len(frames) > 2 else "?"
            future.set_exception(ServiceCallError(f"service {self.srv_name} failed: {reason}"))
            return
        try:
            _, response = decode(frames[:-1], expected_type=self.srv_type.Response)
        except DecodeError as exc:
            self.malformed_count += 1
            future.set_exception(ServiceCallError(f"undecodable response from {self.srv_name}: {exc}"))
            return
        future.set_result(response)

    _ready_queue = ()  # never ready: responses complete futures on the I/O thread

    def _ready(self, now: float) -> bool:
        return False

    def _announcement(self) -> dict:
        return {"name": self.srv_name, "type": self.srv_type.TYPE_NAME}

    def __repr__(self):
        return f"<Client {self.srv_name} [{self.srv_type.TYPE_NAME}]>"
