"""Subscriptions: a ZeroMQ SUB socket drained by the I/O thread into a bounded queue of this subscription.

The runtime's I/O thread receives continuously, whatever the callbacks do, and puts each message
into this subscription's own queue (``queue_limit(qos)`` messages: the QoS depth). When the queue is
full the OLDEST message is dropped and counted, so a slow callback always gets the newest data and
never slows the publisher or any other subscription. Messages are decoded only when the executor
takes them (a dropped message costs no decoding).

Counters (also in the node's announcement, so ``dptpu topic`` tools can show them):

- ``received_count``: messages that arrived (duplicates of TRANSIENT_LOCAL replays excluded);
- ``queue_dropped_count``: dropped as oldest from the full queue;
- ``lost_count``: missing sequence numbers (dropped by ZeroMQ at a full pipe before they arrived);
- ``dropped_count`` = ``queue_dropped_count + lost_count``;
- ``malformed_count``: frames without a valid envelope, or a :class:`~dptpu.messages.DecodeError`
  (logged with the reason, at most once a second per subscription);
- ``taken_count``: messages handed to the callback.

A message that came through shared memory (:mod:`.shared_memory`) is resolved when it arrives: the segment is
mapped and this subscription's shared lock taken, so the publisher does not write it again while the message is
queued or its arrays are alive. A descriptor whose segment was already written again counts as lost.
"""

from __future__ import annotations

import threading
import uuid
from collections import deque
from functools import partial

import zmq

from ..messages.decoder import decode
from ..messages.wire_format import DecodeError
from .known_publishers import KnownPublishers
from .qos import QoSProfile, ReliabilityPolicy, pipe_high_water_mark, queue_limit
from .sequence_tracking import SequenceTracker
from .shared_memory import SharedMemoryError, StaleSegmentError, read_message, shm_topic, short_of_descriptors
from .transport import FLAG_HISTORY, EnvelopeError, configure_client, unpack_envelope

__all__ = ["Subscription", "MessageInfo", "SHM_GIVE_UP"]

#: Descriptors in a row whose segment cannot be opened (not merely recycled) after which a subscription stops
#: taking shared memory (unsubscribes its SHM topic; the publishers then send it everything through ZeroMQ).
SHM_GIVE_UP = 20


class MessageInfo(dict):
    """Per-message metadata: ``source_timestamp`` (ns), ``received_timestamp`` (ns),
    ``publication_sequence_number``, ``publisher_gid`` (hex)."""


class Subscription:
    """Receives messages of one type on one topic (create with ``node.create_subscription``).

    Attributes
    ----------
    msg_type : type or None
        None only for ``raw=True`` subscriptions to any type.
    topic_name : str
        Fully qualified, after remapping.
    callback : callable
        ``callback(msg)``; with ``raw=True`` it gets ``[topic, header, *arrays]`` as memoryviews.
    qos_profile : QoSProfile
    """

    def __init__(self, node, msg_type, topic_name: str, callback, qos_profile: QoSProfile, callback_group,
                 raw: bool = False, known_publishers: KnownPublishers | None = None):
        self._node = node
        self.known_publishers = known_publishers  # None: any publisher (known_publishers)
        self.msg_type = msg_type
        self.topic_name = topic_name
        self.callback = callback
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self.raw = raw
        self.gid = uuid.uuid4().bytes
        self._topic_bytes = topic_name.encode("utf-8")
        resolved = qos_profile.resolved()
        self._limit = queue_limit(resolved)
        self._hwm = pipe_high_water_mark(resolved)
        self._reliable = resolved.reliability == ReliabilityPolicy.RELIABLE
        self._transient = resolved.durability.name == "TRANSIENT_LOCAL"
        self._queue: deque = deque()
        self._ready_queue = self._queue  # the executor skips this subscription while it is empty
        self._lock = threading.Lock()
        self._sequences = SequenceTracker()  # per publisher, bounded (sequence_tracking)
        self.received_count = 0
        self.queue_dropped_count = 0
        self.lost_count = 0
        self.malformed_count = 0
        self.taken_count = 0
        self.exception_count = 0
        self._shm_topic = b""        # set by _open when this process may map other processes' segments
        self._shm_failures = 0       # descriptors in a row whose segment could not be opened
        self._shm_given_up = False   # the SHM topic unsubscribed: everything through ZeroMQ from then on
        self._socket = None          # owned by the I/O thread
        self._connected: dict = {}   # endpoint -> publisher gid (I/O thread)
        self._warned: set = set()    # publisher gids already warned about (I/O thread)
        self._destroyed = False

    @property
    def topic(self) -> str:
        return self.topic_name

    @property
    def dropped_count(self) -> int:
        """Messages this subscription never got to its callback: oldest dropped from the queue + lost in transport."""
        return self.queue_dropped_count + self.lost_count

    def get_publisher_count(self) -> int:
        """Publishers this subscription is connected to now."""
        return len(self._connected)

    def destroy(self) -> bool:
        return self._node.destroy_subscription(self)

    # -- I/O thread side ----------------------------------------------------------------------------

    def _open(self, zmq_context, transport) -> zmq.Socket:
        sock = zmq_context.socket(zmq.SUB)
        sock.setsockopt(zmq.RCVHWM, self._hwm)
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.RECONNECT_IVL, 100)
        sock.setsockopt(zmq.RECONNECT_IVL_MAX, 1000)
        configure_client(sock, transport)
        sock.setsockopt(zmq.SUBSCRIBE, self.topic_name.encode("utf-8"))
        if transport.shared_memory is not None:  # tells the publishers of this host to send descriptors
            self._shm_topic = shm_topic(self._topic_bytes, transport.shared_memory.key)
            sock.setsockopt(zmq.SUBSCRIBE, self._shm_topic)
        self._socket = sock
        return sock

    def _on_message(self, frames) -> bool:
        """Queue one received multipart message; True when it was queued (the executor has work)."""
        if len(frames) < 3:
            self._malformed(f"message of {len(frames)} frame(s); expected topic, header, arrays and envelope")
            return False
        try:
            envelope = unpack_envelope(frames[-1])
        except EnvelopeError as exc:
            self._malformed(str(exc))
            return False
        topic = frames[0].bytes
        shared = topic != self._topic_bytes
        if shared and (topic != self._shm_topic or len(frames) != 4):
            self._malformed(f"message for topic {topic[:80]!r} on a socket of {self.topic_name}")
            return False
        if envelope.flags & FLAG_HISTORY and not self._transient:
            return False  # a TRANSIENT_LOCAL replay; a VOLATILE subscription does not want the past
        verdict = self._sequences.accept(envelope.gid, envelope.seq, history=bool(envelope.flags & FLAG_HISTORY))
        if verdict.note:
            self._node.get_logger().warning(f"subscription on {self.topic_name}, publisher {envelope.gid.hex()[:8]}: "
                                            f"{verdict.note}", throttle_duration_sec=5.0)
        if not verdict.deliver:
            return False  # already delivered (a replay to another late joiner)
        if verdict.lost:
            self.lost_count += verdict.lost
            if self._reliable:
                self._node.get_logger().warning(
                    f"subscription on {self.topic_name} lost {verdict.lost} message(s) from publisher "
                    f"{envelope.gid.hex()[:8]} in transport (its pipe was full); {self.lost_count} lost so far",
                    throttle_duration_sec=5.0)
        if shared:
            try:
                item = (read_message(self._topic_bytes, frames[1], frames[2]), envelope)
                self._shm_failures = 0
                if short_of_descriptors():
                    self._give_up_shared("this process holds most of its file descriptors (ulimit -n): its mapped "
                                         "segments are held by the messages it keeps")
            except StaleSegmentError as exc:
                self._lost_shared(str(exc))
                return False
            except SharedMemoryError as exc:
                self._lost_shared(str(exc))
                self._shm_failures += 1
                if self._shm_failures == SHM_GIVE_UP:
                    self._give_up_shared(f"{SHM_GIVE_UP} shared-memory segments in a row could not be opened")
                return False
        else:
            item = (frames[:-1], envelope)
        with self._lock:
            if len(self._queue) >= self._limit:
                self._queue.popleft()
                self.queue_dropped_count += 1
            self._queue.append(item)
            self.received_count += 1
        return True

    def _give_up_shared(self, reason: str) -> None:
        """Unsubscribe the SHM topic (on the socket's own thread): the publishers send everything through ZeroMQ."""
        sock = self._socket
        if sock is not None and not self._shm_given_up:  # descriptors on their way are still read (topic kept)
            self._shm_given_up = True
            sock.setsockopt(zmq.UNSUBSCRIBE, self._shm_topic)
            self._node.get_logger().error(f"subscription on {self.topic_name}: {reason}; taking every message "
                                          "through ZeroMQ from now on")

    def _malformed(self, reason: str) -> None:
        with self._lock:
            self.malformed_count += 1
        self._node.get_logger().warning(
            f"malformed message on {self.topic_name} ({self.malformed_count} so far): {reason}",
            throttle_duration_sec=1.0)

    def _lost_shared(self, reason: str) -> None:
        with self._lock:
            self.lost_count += 1
        self._node.get_logger().warning(f"subscription on {self.topic_name} lost a message through shared memory "
                                        f"({self.lost_count} lost so far): {reason}", throttle_duration_sec=5.0)

    def _forget_publisher(self, gid: bytes) -> None:
        self._sequences.forget(gid)

    # -- executor side ------------------------------------------------------------------------------

    def _ready(self, now: float) -> bool:
        return bool(self._queue) and not self._destroyed

    def _take(self):
        """The next message's work (a callable), or None when empty or the message was malformed."""
        with self._lock:
            if not self._queue or self._destroyed:
                return None
            frames, envelope = self._queue.popleft()
        if self.raw:
            views = [getattr(frame, "buffer", frame) for frame in frames]  # zmq.Frame, or shared-memory views
            self.taken_count += 1
            return partial(self.callback, views)
        try:
            _, msg = decode(frames, expected_type=self.msg_type)
        except DecodeError as exc:
            self._malformed(str(exc))
            return None
        self.taken_count += 1
        return partial(self.callback, msg)  # a C-level call, no Python frame of its own

    def _describe(self) -> str:
        return f"subscription callback on topic {self.topic_name}"

    def _stats(self) -> dict:
        return {"received_count": self.received_count, "taken_count": self.taken_count,
                "dropped_count": self.dropped_count, "queue_dropped_count": self.queue_dropped_count,
                "lost_count": self.lost_count, "malformed_count": self.malformed_count,
                "exception_count": self.exception_count, "publisher_count": len(self._connected)}

    def _announcement(self) -> dict:
        return {"topic": self.topic_name, "type": self.msg_type.TYPE_NAME if self.msg_type else "*",
                "gid": self.gid.hex(), "qos": self.qos_profile.to_dict(), "stats": self._stats(),
                "shared_memory": bool(self._shm_topic) and not self._shm_given_up}  # whether it maps segments

    def __repr__(self):
        type_name = self.msg_type.TYPE_NAME if self.msg_type else "*"
        return f"<Subscription {self.topic_name} [{type_name}]>"
