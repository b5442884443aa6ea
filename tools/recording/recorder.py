"""Record topics of the graph into an MCAP file (``dptpu record``).

The recorder is an ordinary node (``/dptpu_recorder`` by default). For every requested topic it waits
until the graph's discovery shows a publisher of it, takes the message type from that announcement,
and subscribes with a QoS matched to the publishers, as ``ros2 bag record`` does:

- history KEEP_ALL (a queue of up to ``KEEP_ALL_QUEUE_LIMIT`` messages, so bursts are kept);
- RELIABLE when every publisher offers RELIABLE, else BEST_EFFORT (a RELIABLE subscription would not
  connect to a BEST_EFFORT publisher);
- TRANSIENT_LOCAL when every publisher offers TRANSIENT_LOCAL (so the last ``CameraInfo`` published
  before the recorder started is recorded too), else VOLATILE.

Each message is written with its receive time (``time.time_ns()`` when the executor hands it over) as
the MCAP log time. Topics that appear later are subscribed when they appear. The chosen QoS of each
topic is stored in the metadata record ``dptpu.topic_qos`` so ``dptpu play`` can offer the same.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field

from dptpu.graph.context import Context
from dptpu.graph.executors import SingleThreadedExecutor
from dptpu.graph.node import Node
from dptpu.graph.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from dptpu.messages import lookup
from dptpu.messages.registry import is_registered

from .mcap_io import McapRecordWriter

__all__ = ["Recorder", "RecordResult", "record", "recording_qos", "TOPIC_QOS_METADATA"]

#: Name of the MCAP metadata record holding ``{topic: JSON of QoSProfile.to_dict()}``.
TOPIC_QOS_METADATA = "dptpu.topic_qos"
#: Seconds between two looks at the discovery snapshot for topics not subscribed yet.
DISCOVERY_POLL_S = 0.1


def recording_qos(offered: list) -> QoSProfile:
    """The QoS a recorder subscribes with, given the publishers' offered profiles (None = unknown).

    KEEP_ALL; RELIABLE only if every publisher offers RELIABLE; TRANSIENT_LOCAL only if every
    publisher offers TRANSIENT_LOCAL (ROS 2's request-versus-offered rules then connect to all).
    """
    known = [qos.resolved() for qos in offered if qos is not None]
    reliable = bool(known) and all(qos.reliability == ReliabilityPolicy.RELIABLE for qos in known)
    transient = bool(known) and all(qos.durability == DurabilityPolicy.TRANSIENT_LOCAL for qos in known)
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=0,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)


@dataclass
class RecordResult:
    """What a recording got.

    Attributes
    ----------
    path : str
        The MCAP file.
    counts : dict
        Messages written per requested topic (0 for a topic that never appeared).
    types : dict
        Type name per subscribed topic.
    dropped : dict
        Messages each subscription lost (queue overflow or transport gaps), per subscribed topic.
    missing : list of str
        Requested topics that never appeared in the graph.
    duration_s : float
        Wall-clock seconds from the start to the stop of the recording.
    stop_reason : str
        ``"duration"``, ``"max_messages"`` or ``"interrupted"``.
    """

    path: str
    counts: dict = field(default_factory=dict)
    types: dict = field(default_factory=dict)
    dropped: dict = field(default_factory=dict)
    missing: list = field(default_factory=list)
    duration_s: float = 0.0
    stop_reason: str = ""

    @property
    def total(self) -> int:
        """All messages written."""
        return sum(self.counts.values())


class Recorder:
    """Subscribes ``node`` to ``topics`` as they appear and writes every message to ``writer``.

    Parameters
    ----------
    node : Node
        The node to subscribe with (its executor must spin for messages to arrive).
    writer : McapRecordWriter
        Where messages go; the caller closes it.
    topics : list of str
        Topic names (resolved against the node's namespace; usually absolute, e.g. ``/camera/image_raw``).
    max_messages : int, optional
        Stop writing after this many messages in total (:attr:`done` turns True).
    """

    def __init__(self, node: Node, writer: McapRecordWriter, topics, *, max_messages: int | None = None):
        topics = _check_topics(topics)
        _check_max_messages(max_messages)
        self._node = node
        self._writer = writer
        self._topics = list(dict.fromkeys(node.resolve_topic_name(topic) for topic in topics))
        self._max_messages = max_messages
        self._subscriptions: dict = {}
        self._qos: dict[str, QoSProfile] = {}
        self._counts = {topic: 0 for topic in self._topics}
        self._total = 0
        self._lock = threading.Lock()
        self._warned: set = set()

    @property
    def topics(self) -> list[str]:
        """The requested topics, fully qualified."""
        return list(self._topics)

    @property
    def pending_topics(self) -> list[str]:
        """Requested topics not subscribed yet (no publisher seen)."""
        return [topic for topic in self._topics if topic not in self._subscriptions]

    @property
    def done(self) -> bool:
        """True once ``max_messages`` messages were written."""
        return self._max_messages is not None and self._total >= self._max_messages

    @property
    def subscribed_types(self) -> dict[str, str]:
        """Type name of each subscribed topic."""
        return {topic: sub.msg_type.TYPE_NAME for topic, sub in self._subscriptions.items()}

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per requested topic."""
        with self._lock:
            return dict(self._counts)

    def subscribe_available(self) -> list[str]:
        """Subscribe to every pending topic that has a publisher with a known type now.

        Returns
        -------
        list of str
            The topics subscribed by this call.
        """
        new = []
        for topic in self.pending_topics:
            publishers = self._node.get_publishers_info_by_topic(topic)
            types = sorted({info.type for info in publishers})
            if not types:
                continue
            if len(types) > 1 or not is_registered(types[0]):
                self._warn_once(topic, f"not recording {topic}: its publishers announce type(s) "
                                       f"{', '.join(types)}; expected one registered message type")
                continue
            qos = recording_qos([info.qos for info in publishers])
            self._writer.offer_qos(topic, _offered_profile(publishers, qos))
            msg_type = lookup(types[0])
            self._subscriptions[topic] = self._node.create_subscription(
                msg_type, topic, self._callback(topic), qos)
            self._qos[topic] = qos
            new.append(topic)
        return new

    def _warn_once(self, topic: str, text: str) -> None:
        if topic not in self._warned:
            self._warned.add(topic)
            self._node.get_logger().warning(text)

    def _callback(self, topic: str):
        def write(msg) -> None:
            received_ns = time.time_ns()
            with self._lock:
                if self.done:
                    return
                self._writer.write(topic, msg, received_ns)
                self._counts[topic] += 1
                self._total += 1

        return write

    def result(self, path: str, *, duration_s: float, stop_reason: str) -> RecordResult:
        """A :class:`RecordResult` of what was recorded so far."""
        return RecordResult(
            path=path, counts=self.counts,
            types=self.subscribed_types,
            dropped={topic: sub.dropped_count for topic, sub in self._subscriptions.items()},
            missing=self.pending_topics, duration_s=duration_s, stop_reason=stop_reason)

    def write_qos_metadata(self) -> None:
        """Store each subscribed topic's QoS in the metadata record :data:`TOPIC_QOS_METADATA`."""
        self._writer.add_metadata(TOPIC_QOS_METADATA,
                                  {topic: json.dumps(qos.to_dict()) for topic, qos in self._qos.items()})


def _offered_profile(publishers, chosen: QoSProfile) -> dict:
    """The QoS the channel says was offered: the first publisher's history and depth (ROS 2's default when
    unknown), the reliability and durability every publisher offers (:func:`recording_qos`)."""
    known = [info.qos.resolved() for info in publishers if info.qos is not None]
    profile = known[0].to_dict() if known else {"history": "keep_last", "depth": 10}
    chosen_dict = chosen.to_dict()
    profile.update(reliability=chosen_dict["reliability"], durability=chosen_dict["durability"])
    return profile


def _check_topics(topics) -> list[str]:
    topics = [topics] if isinstance(topics, str) else list(topics)
    if not topics or not all(isinstance(topic, str) and topic for topic in topics):
        raise ValueError(f"topics must be a non-empty list of topic names; got {topics!r}")
    return topics


def _check_max_messages(max_messages) -> None:
    if max_messages is not None and (isinstance(max_messages, bool) or not isinstance(max_messages, int)
                                     or max_messages < 1):
        raise ValueError(f"max_messages must be a positive int; got {max_messages!r}")


def record(output, topics, *, duration_s: float | None = None, max_messages: int | None = None,
           compression: str = "zstd", stop_event: threading.Event | None = None, node_name: str = "dptpu_recorder",
           domain_id: int | None = None, on_subscribed=None) -> RecordResult:
    """Record ``topics`` into the MCAP file ``output`` until stopped.

    Parameters
    ----------
    output : str or os.PathLike
        The ``.mcap`` file to create (overwritten).
    topics : list of str
        Topics to record, e.g. ``["/camera/image_raw", "/scanner/points"]``.
    duration_s : float, optional
        Stop this many seconds after the start (> 0). Default: no limit.
    max_messages : int, optional
        Stop after this many messages in total over all topics (>= 1). Default: no limit.
    compression : {"zstd", "lz4", "none"}
    stop_event : threading.Event, optional
        Stop when it is set (e.g. from a signal handler).
    node_name : str
        Name of the recorder node.
    domain_id : int, optional
        Graph domain (default: ``$DPTPU_DOMAIN_ID``, ``$ROS_DOMAIN_ID``, 0).
    on_subscribed : callable, optional
        ``on_subscribed(topic, type_name)`` after each subscription (e.g. to print progress).

    Returns
    -------
    RecordResult
        Counts per topic, drops, missing topics; the file is complete (summary written) even when
        interrupted by Ctrl-C (``KeyboardInterrupt``) or SIGTERM.
    """
    if duration_s is not None and not (isinstance(duration_s, (int, float)) and duration_s > 0):
        raise ValueError(f"duration_s must be a positive number of seconds; got {duration_s!r}")
    topics = _check_topics(topics)
    _check_max_messages(max_messages)
    start = time.monotonic()
    deadline = None if duration_s is None else start + float(duration_s)
    context = Context()
    context.init(args=[], domain_id=domain_id)
    writer = None
    try:
        node = Node(node_name, context=context, start_parameter_services=False)
        for topic in topics:  # a bad name raises before the file is created
            node.resolve_topic_name(topic)
        writer = McapRecordWriter(output, compression=compression)
        recorder = Recorder(node, writer, topics, max_messages=max_messages)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        stop_reason = "interrupted"
        next_poll = 0.0
        try:
            while True:
                now = time.monotonic()
                if recorder.done:
                    stop_reason = "max_messages"
                    break
                if deadline is not None and now >= deadline:
                    stop_reason = "duration"
                    break
                if stop_event is not None and stop_event.is_set():
                    break
                if now >= next_poll and recorder.pending_topics:
                    for topic in recorder.subscribe_available():
                        if on_subscribed is not None:
                            on_subscribed(topic, recorder.subscribed_types[topic])
                    next_poll = now + DISCOVERY_POLL_S
                wait = DISCOVERY_POLL_S if deadline is None else max(0.0, min(DISCOVERY_POLL_S, deadline - now))
                executor.spin_once(timeout_sec=wait)
        except KeyboardInterrupt:
            stop_reason = "interrupted"
        result = recorder.result(str(output), duration_s=time.monotonic() - start, stop_reason=stop_reason)
        recorder.write_qos_metadata()
        return result
    finally:
        if writer is not None:
            writer.close()
        context.try_shutdown()
