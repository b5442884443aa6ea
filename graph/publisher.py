"""Publishers: one ZeroMQ XPUB socket per publisher, sends that never block.

``publish(msg)`` encodes with :func:`dptpu.messages.encoder.encode`, appends the envelope and sends
with ``copy=False``: the arrays' memory goes to ZeroMQ without a copy, so do not modify an array after
publishing it (allocate a new one per message). The send never blocks: when a subscriber's pipe is
full, ZeroMQ drops the message for that subscriber only (it sees the sequence gap and counts it).

The socket is XPUB so the publisher sees each subscriber connect and leave: that gives
``get_subscription_count()`` and, for TRANSIENT_LOCAL, the moment to replay the kept messages (with
the HISTORY flag; subscribers drop what they already have by sequence number, and VOLATILE ones drop
all replays). A TRANSIENT_LOCAL publisher handles those events before each send and the runtime's I/O
thread every 25 ms; other publishers when asked for their subscriber count, and once a second.

A TRANSIENT_LOCAL publisher's socket is in ``XPUB_MANUAL`` mode: a newcomer's subscription takes
effect only when the publisher, holding its lock, reads the event, subscribes that pipe and replays the
history at once. So the replay always reaches a late subscriber before any live message (with
automatic subscriptions, ZeroMQ could apply the subscription inside the send of a live message).

When every subscriber is a process of this host that can map this one's memory, a message whose arrays hold at
least ``DPTPU_SHM_MIN_BYTES`` goes through shared memory: its arrays are copied once into a segment of this
publisher's pool and ZeroMQ carries the header and a descriptor (:mod:`.shared_memory`, :mod:`.segment_pool`).
A TRANSIENT_LOCAL publisher always sends through ZeroMQ (its history is replayed to late joiners).
A writer that fills its arrays in place can borrow them in a segment (:meth:`Publisher.borrow_loaned_arrays`, as
rclpy's ``borrow_loaned_message``): publishing a message made of them copies nothing. A loan the writer lets go of
unpublished (its arrays garbage, e.g. a frame it dropped) goes back to the pool by itself.
"""

from __future__ import annotations

import math
import threading
import time
import uuid
import weakref
from collections import deque

import numpy as np
import zmq

from ..messages.encoder import encode
from .qos import DurabilityPolicy, QoSProfile, pipe_high_water_mark, queue_limit
from .segment_pool import SegmentPool
from .shared_memory import shm_topic
from .transport import FLAG_HISTORY, bind_endpoints, configure_server, pack_envelope, remove_ipc_file

__all__ = ["Publisher", "PUBLISHER_LINGER_MS"]

#: How long closing a publisher waits for queued messages to leave, ms.
PUBLISHER_LINGER_MS = 200


# pyzmq's flags as plain ints: ``int & zmq.POLLIN`` goes through the enum module's ``__rand__`` (benchmarks, Run 14)
_MORE = int(zmq.SNDMORE | zmq.NOBLOCK)
_NOBLOCK = int(zmq.NOBLOCK)
_EVENTS = int(zmq.EVENTS)
_POLLIN = int(zmq.POLLIN)
#: pyzmq's compiled ``Socket.send`` (``zmq.Socket.send`` only adds the routing-id and group options, unused here).
_backend_send = zmq.backend.Socket.send


def _send(sock, frames: list, envelope: bytes) -> None:
    """Send ``[topic, header, *arrays]`` (from ``codec.encode``) and the envelope as one message, never blocking.

    The topic and header (bytes) are copied into ZeroMQ; the arrays' memoryviews go without a copy
    (pyzmq still copies those below its 64 kB copy threshold, which is cheaper for small ones).
    """
    send = _backend_send
    send(sock, frames[0], _MORE)
    send(sock, frames[1], _MORE)
    for index in range(2, len(frames)):
        send(sock, frames[index], _MORE, copy=False)
    send(sock, envelope, _NOBLOCK)


class Publisher:
    """Publishes messages of one type on one topic (create with ``node.create_publisher``).

    Attributes
    ----------
    msg_type : type
    topic_name : str
        Fully qualified, after remapping.
    qos_profile : QoSProfile
    endpoints : list of str
        Where subscribers connect (announced through discovery).
    published_count : int
        Messages published so far.
    shared_count : int
        Of those, sent through shared memory.
    """

    def __init__(self, node, msg_type, topic_name: str, qos_profile: QoSProfile, callback_group=None):
        self._node = node
        self.msg_type = msg_type
        self.topic_name = topic_name
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self.gid = uuid.uuid4().bytes
        self.created_time = time.time()  # announced: the oldest publisher owns a sole-publisher topic
        self._topic_bytes = topic_name.encode("utf-8")
        runtime = node.context._runtime()
        self._runtime = runtime
        self._lock = threading.Lock()
        self._seq = 0
        self.published_count = 0
        self._subscriber_count = 0
        resolved = qos_profile.resolved()
        self._transient = resolved.durability == DurabilityPolicy.TRANSIENT_LOCAL
        shared = runtime.transport.shared_memory
        # shared memory: the subscribers of this host that can map this process's segments (shm_topic)
        self._pool = (SegmentPool(shared, "dptpu" + topic_name.replace("/", ":"))
                      if shared is not None and not self._transient else None)
        self._shm_topic = shm_topic(self._topic_bytes, shared.key) if shared is not None else b""
        self._shm_min_bytes = shared.min_bytes if shared is not None else 0
        self._shm_subscriber_count = 0
        self.shared_count = 0
        self._loans: dict[tuple, _Loan] = {}  # ((address, nbytes) of each array) -> the loan of exactly them
        # weak references to the loans whose arrays became garbage (appended by the arrays' weak-reference callbacks)
        self._abandoned: deque[weakref.ref[_Loan]] = deque()
        # (sequence number, stamp in ns, encoded frames) of the last messages, replayed to late joiners
        self._history: deque[tuple[int, int, list]] | None = (
            deque(maxlen=queue_limit(resolved)) if self._transient else None)
        sock = runtime.zmq_context.socket(zmq.XPUB)
        try:
            sock.setsockopt(zmq.SNDHWM, pipe_high_water_mark(resolved))
            sock.setsockopt(zmq.RCVHWM, 1000)
            sock.setsockopt(zmq.XPUB_VERBOSER, 1)
            if self._transient:
                # subscriptions take effect only when _handle_events_locked applies them, right before the
                # replay: without it the socket could apply a newcomer's subscription inside the send of a
                # live message, which then reached the newcomer before the replay (docs/graph.md)
                sock.setsockopt(zmq.XPUB_MANUAL, 1)
            sock.setsockopt(zmq.LINGER, PUBLISHER_LINGER_MS)
            configure_server(sock, runtime.transport)
            self.endpoints = bind_endpoints(sock, runtime.transport, runtime.ipc_dir, "p" + self.gid.hex()[:15])
        except BaseException:
            sock.close(linger=0)
            raise
        self._socket = sock
        runtime.add_publisher(self)

    @property
    def topic(self) -> str:
        return self.topic_name

    def publish(self, msg) -> None:
        """Send ``msg`` to every matched subscription; never blocks.

        Raises
        ------
        ValueError
            ``msg`` is not a ``msg_type``, or a field is invalid (``EncodeError``, naming the field).
        RuntimeError
            The publisher was destroyed.
        """
        if not isinstance(msg, self.msg_type):
            raise ValueError(f"publisher on {self.topic_name} expects {self.msg_type.__name__} "
                             f"({self.msg_type.TYPE_NAME}); got {type(msg).__name__}")
        frames = encode(self._topic_bytes, msg)
        with self._lock:
            sock = self._socket
            if sock is None:
                raise RuntimeError(f"publisher on {self.topic_name} was destroyed")
            if self._history is not None:
                self._handle_events_locked()  # replay to a newcomer before any newer message reaches it
            self._seq += 1
            stamp_ns = time.time_ns()
            if self._pool is not None and len(frames) > 2:
                self._handle_events_locked()  # current counts of subscribers (and of those who can map)
                if self._abandoned:
                    self._take_back_abandoned_locked()
                loan = self._loans.pop(_addresses(frames), None) if self._loans else None
                head = self._shared_frames(frames) if loan is None else self._loaned_frames(frames, loan)
                _send(sock, head, pack_envelope(0, self._seq, stamp_ns, self.gid))
            else:
                _send(sock, frames, pack_envelope(0, self._seq, stamp_ns, self.gid))
            self.published_count += 1
            if self._history is not None:
                self._history.append((self._seq, stamp_ns, frames))

    def _shared_frames(self, frames: list) -> list:
        """``[shm topic, header, descriptor]`` when every subscriber can map this process's segments and the
        arrays are large enough (and the pool has room); else ``frames`` as they are."""
        readers, pool = self._subscriber_count, self._pool
        if pool is None or not readers or sum(view.nbytes for view in frames[2:]) < self._shm_min_bytes:
            return frames
        if self._shm_subscriber_count < readers:
            self._note_unmappable(readers)
            return frames
        descriptor = pool.write(frames[2:], readers)
        if descriptor is None:
            return frames  # pool full (every segment held by a subscriber): through ZeroMQ
        self.shared_count += 1
        return [self._shm_topic, frames[1], descriptor]

    def _loaned_frames(self, frames: list, loan: _Loan) -> list:
        """``[shm topic, header, descriptor]`` of a message made of loaned arrays (no copy); or, when a subscriber
        cannot map, the frames with the arrays copied out, and the segment taken back."""
        segment, entries = loan.segment, loan.entries
        for ref in loan.arrays:
            array = ref()
            if array is not None:  # alive: the message being published holds views of it
                array.flags.writeable = False  # the message's now: a subscriber may be reading it
        readers, pool = self._subscriber_count, self._pool
        if pool is None:
            return frames
        if not readers or self._shm_subscriber_count < readers:
            if readers:
                self._note_unmappable(readers)
            copied = [*frames[:2], *(bytes(view) for view in frames[2:])]  # the segment goes back to the pool
            pool.cancel_loan(segment)
            return copied
        self.shared_count += 1
        return [self._shm_topic, frames[1], pool.publish_loan(segment, entries, readers)]

    def _note_unmappable(self, readers: int) -> None:
        """A subscriber that cannot map sends this message through ZeroMQ: said once, naming it (the pool's)."""
        runtime, pool = self._runtime, self._pool
        if pool is not None:
            pool.note_unmappable(self.topic_name, readers, self._shm_subscriber_count, runtime.entries, runtime.host,
                                 runtime.boot_id)

    def borrow_loaned_arrays(self, specs) -> list[np.ndarray]:
        """Writable arrays in one shared-memory segment, to fill in place and publish without a copy.

        As rclpy's ``borrow_loaned_message``: build the message from exactly these arrays, in this order (e.g.
        ``cv2.merge(channels, dst=cloud)`` then ``PointCloud2.from_array(cloud, ...)``) and :meth:`publish` it;
        the arrays are read-only from then on. Without shared memory (off, over tcp, a TRANSIENT_LOCAL
        publisher, a full pool, arrays of fewer than ``DPTPU_SHM_MIN_BYTES`` together) they are plain arrays and
        the message goes as any other. Give back arrays that will not be published with
        :meth:`return_loaned_arrays`; a loan whose arrays become garbage unpublished
        goes back to the pool by itself (at the next publish or borrow).

        Parameters
        ----------
        specs : sequence of (shape, dtype)
            One entry per array, in the order the message's encoding lists them.

        Returns
        -------
        list of ndarray
            C-contiguous, uninitialized, each starting at a 64-byte boundary. Keep them (not only views of them)
            until the message is published: a loan is matched by its arrays' addresses, and one whose arrays are
            garbage counts as let go.

        Raises
        ------
        ValueError
            A dtype that holds Python objects (``object``, or records with such fields).
        """
        specs = [(tuple(int(n) for n in shape), np.dtype(dtype)) for shape, dtype in specs]
        for _, dtype in specs:
            if dtype.hasobject:  # a segment cannot hold Python objects (the view failed after the loan was taken)
                raise ValueError(f"borrow_loaned_arrays on {self.topic_name}: dtype {dtype} holds Python objects; "
                                 "expected plain data (numbers, bools, records of them)")
        sizes = [math.prod(shape) * dtype.itemsize for shape, dtype in specs]  # math's: np.prod costs ~7 us
        with self._lock:
            if self._abandoned:
                self._take_back_abandoned_locked()
            pool = self._pool
            lend = pool is not None and self._socket is not None and sum(sizes) >= self._shm_min_bytes
            taken = pool.loan(sizes) if pool is not None and lend else None
            if taken is None:
                return [np.empty(shape, dtype) for shape, dtype in specs]
            segment, entries = taken
            arrays = [segment.array[offset:offset + nbytes].view(dtype).reshape(shape)
                      for (offset, nbytes), (shape, dtype) in zip(entries, specs)]
            key = tuple((array.ctypes.data, nbytes) for array, (_, nbytes) in zip(arrays, entries))
            self._loans[key] = _Loan(segment, entries, key, arrays, self._abandoned)
        return arrays

    def can_loan_messages(self, nbytes: int | None = None) -> bool:
        """Whether arrays borrowed now (``nbytes`` of them together, when given) would be a shared-memory loan
        that :meth:`publish` sends without a copy (as rclcpp's ``Publisher::can_loan_messages``): shared memory
        is on, and every subscriber connected now can map this process's segments. Otherwise a writer does better
        to publish its own arrays (ZeroMQ sends them without a copy) than to fill borrowed plain ones."""
        with self._lock:
            if self._pool is None or self._socket is None:
                return False
            self._handle_events_locked()  # current counts of subscribers (and of those who can map)
            readers = self._subscriber_count
            return (readers > 0 and self._shm_subscriber_count >= readers
                    and (nbytes is None or nbytes >= self._shm_min_bytes))

    def return_loaned_arrays(self, arrays) -> None:
        """Give back arrays of :meth:`borrow_loaned_arrays` that will not be published (nothing for plain ones)."""
        key = tuple((array.ctypes.data, array.nbytes) for array in arrays)
        with self._lock:
            loan = self._loans.pop(key, None)
            if loan is not None and self._pool is not None:
                self._pool.cancel_loan(loan.segment)

    def _take_back_abandoned_locked(self) -> None:
        """Cancel the loans whose arrays became garbage before they were published (holding the lock)."""
        while self._abandoned:
            loan = self._abandoned.popleft()()
            if loan is not None and self._loans.get(loan.key) is loan:  # not published, returned or lent again since
                del self._loans[loan.key]
                if self._pool is not None:
                    self._pool.cancel_loan(loan.segment)

    def get_subscription_count(self) -> int:
        """Subscriptions connected now (as the socket has seen them join and leave)."""
        # the TRANSIENT_LOCAL publishers of this process first: a caller that starts publishing once
        # subscribers are there should not overtake the replays to those subscribers
        self._runtime.service_transient_local_publishers()
        if self._history is None:
            self._service_events()
        return self._subscriber_count

    def wait_for_subscriptions(self, count: int = 1, timeout_sec: float | None = None) -> bool:
        """Block until at least ``count`` subscriptions are connected (not in rclpy); True when they are."""
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while self.get_subscription_count() < count:
            if deadline is not None and time.monotonic() >= deadline:
                return False
            time.sleep(0.005)
        return True

    def destroy(self) -> bool:
        return self._node.destroy_publisher(self)

    # -- runtime side (I/O thread) ------------------------------------------------------------------

    def _service_events(self) -> None:
        """Handle subscribe/unsubscribe events: count subscribers, replay history to newcomers."""
        with self._lock:
            self._handle_events_locked()

    def _handle_events_locked(self) -> None:
        sock = self._socket
        if sock is None:
            return
        replay = False
        while sock.getsockopt(_EVENTS) & _POLLIN:
            try:
                event = sock.recv(_NOBLOCK)
            except zmq.Again:
                break
            if event[:1] == b"\x01":
                if self._transient:  # XPUB_MANUAL: subscribe the pipe the event came from, now
                    sock.setsockopt(zmq.SUBSCRIBE, event[1:])
                if event[1:] == self._topic_bytes:
                    self._subscriber_count += 1
                    replay = True
                elif event[1:] == self._shm_topic:  # a subscriber of this host that can map this one's memory
                    self._shm_subscriber_count += 1
            elif event[:1] == b"\x00":
                if self._transient:
                    sock.setsockopt(zmq.UNSUBSCRIBE, event[1:])
                if event[1:] == self._topic_bytes:
                    self._subscriber_count = max(0, self._subscriber_count - 1)
                elif event[1:] == self._shm_topic:
                    self._shm_subscriber_count = max(0, self._shm_subscriber_count - 1)
        if replay and self._history:
            for seq, stamp_ns, frames in self._history:
                _send(sock, frames, pack_envelope(FLAG_HISTORY, seq, stamp_ns, self.gid))

    def _close(self) -> None:
        with self._lock:
            sock, self._socket = self._socket, None
            if self._history is not None:
                self._history.clear()
            self._loans.clear()
            self._abandoned.clear()
        if sock is not None:
            sock.close(linger=PUBLISHER_LINGER_MS)
            if self._pool is not None:
                self._pool.close()
            for endpoint in self.endpoints:
                remove_ipc_file(endpoint)  # libzmq leaves the socket file behind

    def _announcement(self) -> dict:
        return {"topic": self.topic_name, "type": self.msg_type.TYPE_NAME, "gid": self.gid.hex(),
                "endpoints": list(self.endpoints), "qos": self.qos_profile.to_dict(),
                "created_time": self.created_time, "stats": {"published_count": self.published_count,
                          "subscription_count": self._subscriber_count, "shared_count": self.shared_count}}

    def __repr__(self):
        return f"<Publisher {self.topic_name} [{self.msg_type.TYPE_NAME}]>"


class _Loan:
    """Arrays lent in one segment: the segment, each array's ``(offset, nbytes)``, the key (each array's
    ``(address, nbytes)``) and weak references to the arrays (a loan let go of unpublished goes back).

    An array that becomes garbage while its loan is held (by the publisher's table of unpublished loans) puts a
    weak reference to the loan on ``abandoned`` (a weak reference's callback: a tenth of a ``weakref.finalize``;
    ``deque.append`` is thread-safe). Once the loan is published or returned and dropped, its references go with
    it and call nothing."""

    __slots__ = ("segment", "entries", "key", "arrays", "__weakref__")

    def __init__(self, segment, entries, key: tuple, arrays: list[np.ndarray], abandoned: deque):
        self.segment = segment
        self.entries = entries
        self.key = key
        me = weakref.ref(self)  # the callbacks hold the loan weakly: no cycle through its own references

        def let_go(_ref, me=me, append=abandoned.append):
            append(me)

        self.arrays = [weakref.ref(array, let_go) for array in arrays]


def _addresses(frames: list) -> tuple:
    """``((address, nbytes), ...)`` of a message's array frames: the key of a loan made of exactly them."""
    return tuple((np.frombuffer(view, dtype=np.uint8).ctypes.data, view.nbytes) for view in frames[2:])
