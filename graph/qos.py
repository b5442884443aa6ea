"""Quality of service: history, depth, reliability and durability, with rclpy's names and presets.

What each policy does here (``docs/graph.md`` has the full story):

- ``history=KEEP_LAST, depth=N``: every subscription has its own queue of at most ``N`` messages; when
  it is full the OLDEST message is dropped and counted (``subscription.dropped_count``). The
  publisher keeps ``N`` messages for TRANSIENT_LOCAL late joiners.
- ``KEEP_ALL``: the queue holds up to :data:`KEEP_ALL_QUEUE_LIMIT` messages (bounded memory).
- ``RELIABLE``: ZeroMQ pipes of :func:`pipe_messages` messages absorb bursts; nothing is lost
  while the subscriber keeps up. A publisher never blocks: if a subscriber stalls long enough for its
  pipe to fill, ZeroMQ drops new messages for that subscriber only; the subscriber sees the gap in the
  sequence numbers, counts it (``lost_count``) and logs a warning.
- ``BEST_EFFORT``: pipes of only ``depth`` messages, so stale data is dropped early; gaps are counted
  but not logged. (A pipe's ZeroMQ high-water mark is twice what it must absorb:
  :func:`pipe_high_water_mark`.)
- ``VOLATILE``: a subscription gets what is published after it connected.
- ``TRANSIENT_LOCAL``: the publisher also delivers its last ``depth`` messages to late subscriptions
  that ask for TRANSIENT_LOCAL.

Compatibility, as ROS 2: a RELIABLE subscription does not connect to a BEST_EFFORT publisher, and a
TRANSIENT_LOCAL subscription does not connect to a VOLATILE publisher (both sides log a warning).
"""

from __future__ import annotations

from enum import IntEnum

from .exceptions import InvalidQoSProfileException

__all__ = [
    "HistoryPolicy",
    "ReliabilityPolicy",
    "DurabilityPolicy",
    "QoSProfile",
    "qos_profile_default",
    "qos_profile_system_default",
    "qos_profile_sensor_data",
    "qos_profile_services_default",
    "qos_profile_parameters",
    "qos_profile_parameter_events",
    "as_qos_profile",
    "qos_compatibility",
    "pipe_high_water_mark",
    "pipe_messages",
    "queue_limit",
    "KEEP_ALL_QUEUE_LIMIT",
    "RELIABLE_PIPE_MESSAGES",
]

#: Most messages a KEEP_ALL subscription queue holds before it drops the oldest.
KEEP_ALL_QUEUE_LIMIT = 1000
#: Messages a RELIABLE pipe (each of the publisher's and the subscriber's ZeroMQ queues) absorbs.
RELIABLE_PIPE_MESSAGES = 100
#: Depth that SYSTEM_DEFAULT history resolves to.
SYSTEM_DEFAULT_DEPTH = 10


class HistoryPolicy(IntEnum):
    """How many samples are kept (rclpy values)."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2


class ReliabilityPolicy(IntEnum):
    """Whether losses are tolerated (rclpy values)."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2


class DurabilityPolicy(IntEnum):
    """Whether late joiners get past samples (rclpy values)."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class QoSProfile:
    """A quality-of-service profile (rclpy's ``QoSProfile``, the policies this runtime honours).

    Mutable like rclpy's (``qos.durability = DurabilityPolicy.TRANSIENT_LOCAL``); an entity copies
    the profile when it is created, so later changes do not affect it.

    Parameters
    ----------
    history : HistoryPolicy
        KEEP_LAST (default) or KEEP_ALL.
    depth : int
        Queue length for KEEP_LAST, >= 0 (0 with KEEP_LAST is treated as 1).
    reliability : ReliabilityPolicy
        RELIABLE (default) or BEST_EFFORT.
    durability : DurabilityPolicy
        VOLATILE (default) or TRANSIENT_LOCAL.

    Raises
    ------
    InvalidQoSProfileException
        For an unknown keyword, a policy that is not one of the enum values, or a negative depth.
    """

    __slots__ = ("_history", "_depth", "_reliability", "_durability")

    def __init__(self, *, history=HistoryPolicy.KEEP_LAST, depth: int = 10,
                 reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE):
        self._history = _policy(HistoryPolicy, history, "history")
        self._reliability = _policy(ReliabilityPolicy, reliability, "reliability")
        self._durability = _policy(DurabilityPolicy, durability, "durability")
        self._depth = _depth(depth)

    @property
    def history(self) -> HistoryPolicy:
        return self._history

    @history.setter
    def history(self, value):
        self._history = _policy(HistoryPolicy, value, "history")

    @property
    def depth(self) -> int:
        """Messages kept (KEEP_LAST)."""
        return self._depth

    @depth.setter
    def depth(self, value):
        self._depth = _depth(value)

    @property
    def reliability(self) -> ReliabilityPolicy:
        return self._reliability

    @reliability.setter
    def reliability(self, value):
        self._reliability = _policy(ReliabilityPolicy, value, "reliability")

    @property
    def durability(self) -> DurabilityPolicy:
        return self._durability

    @durability.setter
    def durability(self, value):
        self._durability = _policy(DurabilityPolicy, value, "durability")

    def resolved(self) -> QoSProfile:
        """SYSTEM_DEFAULT policies replaced by what they mean here (KEEP_LAST 10, RELIABLE, VOLATILE)."""
        history = HistoryPolicy.KEEP_LAST if self._history == HistoryPolicy.SYSTEM_DEFAULT else self._history
        depth = self._depth if self._depth or history == HistoryPolicy.KEEP_ALL else (
            SYSTEM_DEFAULT_DEPTH if self._history == HistoryPolicy.SYSTEM_DEFAULT else 1)
        reliability = (ReliabilityPolicy.RELIABLE if self._reliability == ReliabilityPolicy.SYSTEM_DEFAULT
                       else self._reliability)
        durability = (DurabilityPolicy.VOLATILE if self._durability == DurabilityPolicy.SYSTEM_DEFAULT
                      else self._durability)
        return QoSProfile(history=history, depth=depth, reliability=reliability, durability=durability)

    def to_dict(self) -> dict:
        """``{"history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile"}``."""
        return {"history": self._history.name.lower(), "depth": self._depth,
                "reliability": self._reliability.name.lower(), "durability": self._durability.name.lower()}

    @classmethod
    def from_dict(cls, data: dict) -> QoSProfile:
        """Inverse of :meth:`to_dict` (unknown or missing keys raise InvalidQoSProfileException)."""
        try:
            return cls(history=HistoryPolicy[str(data["history"]).upper()], depth=int(data["depth"]),
                       reliability=ReliabilityPolicy[str(data["reliability"]).upper()],
                       durability=DurabilityPolicy[str(data["durability"]).upper()])
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidQoSProfileException(f"not a QoS profile dict: {data!r} ({exc})") from None

    def __eq__(self, other):
        if not isinstance(other, QoSProfile):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    # mutable; typeshed declares object.__hash__ a method, so "unhashable" (None) is not expressible as its override
    __hash__ = None  # type: ignore[assignment]

    def copy(self) -> QoSProfile:
        return QoSProfile(history=self._history, depth=self._depth, reliability=self._reliability,
                          durability=self._durability)

    def __repr__(self):
        return (f"QoSProfile(history={self._history.name}, depth={self._depth}, "
                f"reliability={self._reliability.name}, durability={self._durability.name})")


def _depth(value) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise InvalidQoSProfileException(f"QoS depth must be an int >= 0; got {value!r}")
    return int(value)


def _policy(enum_cls, value, what: str):
    try:
        return enum_cls(value)
    except ValueError:
        names = ", ".join(member.name for member in enum_cls)
        raise InvalidQoSProfileException(f"QoS {what} must be one of {names}; got {value!r}") from None


def as_qos_profile(qos) -> QoSProfile:
    """A copy of a QoSProfile, or an int depth shorthand (``10`` -> ``QoSProfile(depth=10)``), as a QoSProfile.

    Raises
    ------
    InvalidQoSProfileException
        Anything else, e.g. ``None`` or ``"10"``.
    """
    if isinstance(qos, QoSProfile):
        return qos.copy()
    if isinstance(qos, int) and not isinstance(qos, bool):
        return QoSProfile(depth=qos)
    raise InvalidQoSProfileException(f"qos_profile must be a QoSProfile or an int depth (e.g. 10); got {qos!r}")


def qos_compatibility(publisher: QoSProfile, subscription: QoSProfile) -> str | None:
    """None when the two connect, else the reason they do not (ROS 2 request-versus-offered rules)."""
    publisher, subscription = publisher.resolved(), subscription.resolved()
    if (subscription.reliability == ReliabilityPolicy.RELIABLE
            and publisher.reliability == ReliabilityPolicy.BEST_EFFORT):
        return "the subscription requests RELIABLE but the publisher offers BEST_EFFORT"
    if (subscription.durability == DurabilityPolicy.TRANSIENT_LOCAL
            and publisher.durability == DurabilityPolicy.VOLATILE):
        return "the subscription requests TRANSIENT_LOCAL but the publisher offers VOLATILE"
    return None


def queue_limit(qos: QoSProfile) -> int:
    """Messages a subscription queue (or a publisher's late-joiner history) holds."""
    qos = qos.resolved()
    return KEEP_ALL_QUEUE_LIMIT if qos.history == HistoryPolicy.KEEP_ALL else max(qos.depth, 1)


def pipe_messages(qos: QoSProfile) -> int:
    """Messages one ZeroMQ pipe of a connection with this QoS must absorb: ``depth`` for BEST_EFFORT,
    ``max(depth, RELIABLE_PIPE_MESSAGES)`` for RELIABLE."""
    qos = qos.resolved()
    if qos.reliability == ReliabilityPolicy.BEST_EFFORT:
        return queue_limit(qos)
    return max(queue_limit(qos), RELIABLE_PIPE_MESSAGES)


def pipe_high_water_mark(qos: QoSProfile) -> int:
    """ZeroMQ send/receive high-water mark (messages) of one connection with this QoS: twice
    :func:`pipe_messages`.

    libzmq tells a pipe's writer about the reader's progress only every ``(hwm + 1) // 2`` messages (the
    pipe's low-water mark), so a pipe of high-water mark ``n`` may refuse a message while only about
    ``n / 2`` are unread. Twice the messages it must absorb makes sure it holds at least that many, so a
    burst of ``depth`` messages reaches the subscription's queue, which then drops the OLDEST, instead of
    ZeroMQ dropping the newest at the pipe (measured: 6 of 96 outstanding 640x480 frames lost with the
    high-water mark at the depth of 100).
    """
    return 2 * pipe_messages(qos)


qos_profile_default = QoSProfile(depth=10)
qos_profile_system_default = QoSProfile(history=HistoryPolicy.SYSTEM_DEFAULT, depth=0,
                                        reliability=ReliabilityPolicy.SYSTEM_DEFAULT,
                                        durability=DurabilityPolicy.SYSTEM_DEFAULT)
qos_profile_sensor_data = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
qos_profile_services_default = QoSProfile(depth=10)
qos_profile_parameters = QoSProfile(depth=1000)
qos_profile_parameter_events = QoSProfile(depth=1000)
