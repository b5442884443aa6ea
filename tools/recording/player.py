"""Publish the messages of an MCAP recording on their topics (``dptpu play``).

The player is an ordinary node (``/dptpu_player`` by default) with one publisher per recorded topic
it can decode (:func:`~dptpu.tools.recording.mcap_io.describe_mcap` ``readable``). Messages go out in
log-time order with the recorded spacing divided by ``rate``: message ``i`` is published at
``start + (log_time_i - log_time_0) / rate``. Headers are published as recorded (stamps are not
rewritten), like ``ros2 bag play``.

QoS: every publisher is RELIABLE (it then connects to RELIABLE and BEST_EFFORT subscriptions); a topic
the recorder subscribed TRANSIENT_LOCAL (metadata ``dptpu.topic_qos``) is published TRANSIENT_LOCAL with
depth 1, so a late subscription still gets the last message, e.g. the last ``CameraInfo``.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field

from dptpu.graph.context import Context
from dptpu.graph.node import Node
from dptpu.graph.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from dptpu.messages import lookup

from .mcap_io import describe_mcap, read_mcap, read_metadata, verify_mcap
from .recorder import TOPIC_QOS_METADATA

__all__ = ["PlayResult", "play", "playback_qos", "PLAYBACK_DEPTH"]

#: KEEP_LAST depth of a VOLATILE playback publisher (how many messages its pipes absorb in a burst).
PLAYBACK_DEPTH = 100
_SLEEP_SLICE_S = 0.05


def playback_qos(recorded: dict | None) -> QoSProfile:
    """The QoS a player publishes a topic with, from the recorder's profile dict (or None).

    RELIABLE always; TRANSIENT_LOCAL with depth 1 when the recording's subscription was
    TRANSIENT_LOCAL, else VOLATILE with depth :data:`PLAYBACK_DEPTH`.
    """
    transient = recorded is not None and str(recorded.get("durability", "")).lower() == "transient_local"
    if transient:
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=PLAYBACK_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


@dataclass
class PlayResult:
    """What a playback published.

    Attributes
    ----------
    counts : dict
        Messages published per topic (over all loops).
    types : dict
        Type name per published topic.
    skipped : dict
        Topics of the file that were not played, with the reason (a type we do not have, ...).
    unmatched : list of str
        Topics that had no subscription when playback started (only checked with
        ``wait_for_subscribers_s > 0``).
    loops : int
        Complete passes through the file.
    duration_s : float
        Wall-clock seconds of the playback (without ``delay_s`` and the wait for subscribers).
    """

    counts: dict = field(default_factory=dict)
    types: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)
    unmatched: list = field(default_factory=list)
    loops: int = 0
    duration_s: float = 0.0

    @property
    def total(self) -> int:
        """All messages published."""
        return sum(self.counts.values())


def play(path, *, rate: float = 1.0, loop: bool = False, topics=None, delay_s: float = 0.0,
         wait_for_subscribers_s: float = 0.0, stop_event: threading.Event | None = None,
         node_name: str = "dptpu_player", domain_id: int | None = None, on_ready=None) -> PlayResult:
    """Publish the recorded messages of ``path`` with the recorded timing scaled by ``rate``.

    Parameters
    ----------
    path : str or os.PathLike
        An MCAP file (from ``dptpu record`` or any ROS 2 bag of types we have).
    rate : float
        Playback speed factor (> 0): 2 plays twice as fast, 0.5 at half speed.
    loop : bool
        Start again at the end, until stopped (``stop_event``, Ctrl-C or SIGTERM).
    topics : list of str, optional
        Only these topics (default: every readable topic of the file).
    delay_s : float
        Seconds to sleep after creating the publishers, before the first message (>= 0).
    wait_for_subscribers_s : float
        Wait up to this many seconds until every topic has at least one subscription (>= 0; 0 = do
        not wait). Topics still without one are listed in ``PlayResult.unmatched``.
    stop_event : threading.Event, optional
        Stop when it is set.
    node_name : str
    domain_id : int, optional
        Graph domain (default: ``$DPTPU_DOMAIN_ID``, ``$ROS_DOMAIN_ID``, 0).
    on_ready : callable, optional
        ``on_ready(result)`` once the publishers exist and the waits are over (e.g. to print a plan).

    Returns
    -------
    PlayResult

    Raises
    ------
    FileNotFoundError, McapReadError
        The file is missing, unreadable or corrupt (a CRC that does not match: nothing is published).
    ValueError
        A bad argument, a requested topic the file lacks, or no playable topic.
    """
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not rate > 0:
        raise ValueError(f"rate must be a positive number; got {rate!r}")
    for name, value in (("delay_s", delay_s), ("wait_for_subscribers_s", wait_for_subscribers_s)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
            raise ValueError(f"{name} must be a number of seconds >= 0; got {value!r}")
    verify_mcap(path)  # every CRC once, before anything is published (each pass still checks chunk CRCs)
    channels = {channel.topic: channel for channel in describe_mcap(path)}
    result = PlayResult()
    wanted = list(channels) if topics is None else list(dict.fromkeys(topics))
    absent = [topic for topic in wanted if topic not in channels]
    if absent:
        raise ValueError(f"{path} has no topic(s) {', '.join(absent)}; it has {', '.join(channels) or 'none'}")
    for topic in wanted:
        channel = channels[topic]
        if channel.readable:
            result.types[topic] = channel.type_name
        else:
            result.skipped[topic] = f"{channel.type_name or 'no schema'} ({channel.message_encoding})"
    if not result.types:
        raise ValueError(f"{path} has no topic dptpu can play; skipped: {result.skipped}")
    recorded_qos = _recorded_qos(path)
    context = Context()
    context.init(args=[], domain_id=domain_id)
    try:
        node = Node(node_name, context=context, start_parameter_services=False)
        publishers = {topic: node.create_publisher(lookup(type_name), topic, playback_qos(recorded_qos.get(topic)))
                      for topic, type_name in result.types.items()}
        result.counts = {topic: 0 for topic in publishers}
        if wait_for_subscribers_s > 0:
            deadline = time.monotonic() + wait_for_subscribers_s
            for publisher in publishers.values():
                publisher.wait_for_subscriptions(1, timeout_sec=max(0.0, deadline - time.monotonic()))
            result.unmatched = [topic for topic, publisher in publishers.items()
                                if publisher.get_subscription_count() < 1]
        if delay_s > 0 and _sleep_until(time.monotonic() + delay_s, stop_event):
            return result
        if on_ready is not None:
            on_ready(result)
        start = time.monotonic()
        try:
            while True:
                if _play_once(path, publishers, rate, stop_event, result):
                    break
                result.loops += 1
                if not loop:
                    break
        except KeyboardInterrupt:
            pass
        result.duration_s = time.monotonic() - start
        return result
    finally:
        context.try_shutdown()  # publishers close with a linger, so queued messages still leave


def _recorded_qos(path) -> dict:
    """``{topic: QoS dict}`` from the ``dptpu.topic_qos`` metadata (empty when absent or malformed)."""
    out = {}
    for topic, text in read_metadata(path).get(TOPIC_QOS_METADATA, {}).items():
        try:
            value = json.loads(text)
        except ValueError:
            continue
        if isinstance(value, dict):
            out[topic] = value
    return out


def _sleep_until(target: float, stop_event) -> bool:
    """Sleep until monotonic time ``target``; True when ``stop_event`` was set meanwhile."""
    while True:
        if stop_event is not None and stop_event.is_set():
            return True
        remaining = target - time.monotonic()
        if remaining <= 0:
            return False
        time.sleep(min(remaining, _SLEEP_SLICE_S))


def _play_once(path, publishers: dict, rate: float, stop_event, result: PlayResult) -> bool:
    """One pass through the file; True when stopped early."""
    first_log_ns = None
    start = time.monotonic()
    for topic, msg, log_time_ns in read_mcap(path, topics=list(publishers), skip_unknown=True, verify=False):
        if first_log_ns is None:
            first_log_ns = log_time_ns
        target = start + (log_time_ns - first_log_ns) / 1e9 / rate
        if _sleep_until(target, stop_event):
            return True
        publishers[topic].publish(msg)
        result.counts[topic] += 1
    return stop_event is not None and stop_event.is_set()
