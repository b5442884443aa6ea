"""The plumbing the scanner's nodes share: topic QoS, the default optical frame, ScanStatus reports, back-off.

Each process subpackage (``dptpu.nodes.phase``, ``...cloud``, ...) takes these from here rather than from another
node's modules, so no node borrows a helper of another.

- :data:`DEFAULT_FRAME_ID`: the camera optical frame of frames, clouds and depth images (docs/messages.md).
- :data:`STATUS_QOS`, :data:`LATCHED_QOS`: the ``/scanner/status`` publishers of the processing nodes (one
  report a scan; deep enough for a burst of failed scans) and the transient-local topics that keep their last
  message for late joiners (``/camera/camera_info``, ``/projector/pattern_sequence``).
- :func:`scan_status`: one :class:`~dptpu.messages.ScanStatus` from a node, stamped now and named after it.
- :class:`ScanFailures` and :func:`fails_the_scan`: an exception raised while a node works on a scan becomes
  that scan's ``failed`` ScanStatus, naming the node and the exception in one line (the traceback goes to the
  node's log), so the scan monitor says which node failed and why instead of "no cloud within ...".
- :class:`DecodeErrorCount`: the messages a node's subscriptions could not decode since its last report (the
  ``decode_errors`` field of each ScanStatus).
- :func:`backoff_delay_s`: the reconnection back-off of the links to hardware (the projector's serial port, the
  camera).
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar, cast

from dptpu.graph.node import Node
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import Header, ScanStatus, Time

__all__ = ["DEFAULT_FRAME_ID", "LATCHED_QOS", "STATUS_QOS", "DecodeErrorCount", "ScanFailures", "backoff_delay_s",
           "fails_the_scan", "scan_status"]

#: ``header.frame_id`` of the camera optical frame (x right, y down, z forward), the default of every node.
DEFAULT_FRAME_ID = "scanner_optical_frame"
#: ``/scanner/status`` publishers of the processing nodes (phase, unwrap, cloud, sim): reliable, depth 50.
STATUS_QOS = QoSProfile(depth=50)
#: Topics whose last message a late subscriber still gets: reliable, transient local, depth 1.
LATCHED_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def scan_status(node: Node, sequence_id: int, level: int, state: str, reason: str = "", *, stamp: Time | None = None,
                **fields) -> ScanStatus:
    """A ScanStatus of scan ``sequence_id`` from ``node``: stamped ``stamp`` (default: the node's clock now),
    ``node`` its fully qualified name; ``fields`` are the other ScanStatus fields (``frames_expected``,
    ``duration_s``, ...)."""
    stamp = node.get_clock().now().to_msg() if stamp is None else stamp
    return ScanStatus(header=Header(stamp=stamp, frame_id=""), sequence_id=sequence_id, level=level, state=state,
                      reason=reason, node=node.get_fully_qualified_name(), **fields)


#: The most characters of an exception's message that a failed ScanStatus's reason carries (the log has it all).
_MESSAGE_CHARS = 300


class ScanFailures:
    """Exceptions raised while a node works on a scan, each reported as that scan's failure.

    An exception that escapes a scan callback would otherwise reach the executor, which logs it and goes on: the
    scan then simply never ends, and the scan monitor can only call it LOST, naming the nodes that did report it.
    :meth:`report` logs the exception with its traceback (ERROR) and publishes a ``failed`` ScanStatus (level
    ERROR) whose reason names the exception's type and message in one line; ``ScanStatus.node`` names the node.
    A scan is reported once, however many of its messages fail in a row (the sim node serves a scan's frames one
    by one).

    Parameters
    ----------
    node : Node
        The node whose scans these are (it names the status).
    status_publisher : Publisher
        The node's ``/scanner/status`` publisher.

    Attributes
    ----------
    count : int
        Scans failed by an exception so far.
    """

    def __init__(self, node: Node, status_publisher):
        self._node = node
        self._publisher = status_publisher
        self._last_failed: int | None = None
        self.count = 0

    def report(self, sequence_id: int, exc: Exception, during: str) -> str:
        """Log ``exc`` (raised in ``during``, e.g. the method's name) and fail scan ``sequence_id``; the reason.

        The reason reads ``TypeError: <message> (in on_absolute_phase; traceback in the node's log)``: one line
        (a multi-line message's lines joined, at most :data:`_MESSAGE_CHARS` characters of it) that the scan
        monitor prints after the node's name.
        """
        message = " ".join(str(exc).split()) or "(no message)"
        if len(message) > _MESSAGE_CHARS:
            message = message[:_MESSAGE_CHARS - 3] + "..."
        reason = f"{type(exc).__name__}: {message} (in {during}; traceback in the node's log)"
        if sequence_id == self._last_failed:  # the same scan's next message failing: reported already
            self._node.get_logger().error(f"scan {sequence_id} failed again in {during}: {reason}",
                                          throttle_duration_sec=1.0)
            return reason
        self._last_failed = sequence_id
        self.count += 1
        self._node.get_logger().error(f"scan {sequence_id} failed in {during}: {type(exc).__name__}: {exc}",
                                      exc_info=(type(exc), exc, exc.__traceback__))
        self._publisher.publish(scan_status(self._node, sequence_id, ScanStatus.ERROR, "failed", reason))
        return reason


_Method = TypeVar("_Method", bound=Callable[..., Any])


def fails_the_scan(sequence_id_of: Callable[[Any], int]) -> Callable[[_Method], _Method]:
    """Decorator of a node method whose first argument is one scan's message: an exception the method raises fails
    that scan (:meth:`ScanFailures.report` of the node's ``scan_failures``) instead of reaching the executor.

    ``sequence_id_of(message)`` names the scan, e.g. ``lambda msg: msg.sequence_id``. The node sets
    ``self.scan_failures = ScanFailures(self, status_publisher)`` in its ``__init__``. The method returns None
    when it failed.

    Examples
    --------
    >>> class CloudNode(Node):
    ...     @fails_the_scan(lambda msg: msg.sequence_id)
    ...     def _triangulate(self, msg: AbsolutePhase) -> None: ...
    """
    def decorate(method: _Method) -> _Method:
        @functools.wraps(method)
        def guarded(node, message, *args, **kwargs):
            try:
                return method(node, message, *args, **kwargs)
            except Exception as exc:  # noqa: BLE001 -- any exception is this scan's failure, reported as such
                node.scan_failures.report(int(sequence_id_of(message)), exc, method.__name__)
                return None
        return cast(_Method, guarded)
    return decorate


class DecodeErrorCount:
    """Messages that ``subscriptions`` could not decode, counted once each: :meth:`since_last_report` gives those
    since its previous call (``ScanStatus.decode_errors``).

    Parameters
    ----------
    subscriptions : Subscription
        Subscriptions whose ``malformed_count`` is summed; more can be added with :meth:`add`.
    """

    def __init__(self, *subscriptions):
        self._subscriptions = list(subscriptions)
        self._reported = 0

    def add(self, subscription) -> None:
        """Count the malformed messages of ``subscription`` too."""
        self._subscriptions.append(subscription)

    def since_last_report(self) -> int:
        """Malformed messages since the previous call (all of them at the first call)."""
        malformed = sum(s.malformed_count for s in self._subscriptions)
        new, self._reported = malformed - self._reported, malformed
        return new


def backoff_delay_s(attempt: int, initial_s: float, max_s: float) -> float:
    """Delay before reconnection attempt ``attempt`` (0-based): ``min(initial_s * 2**attempt, max_s)``."""
    return min(initial_s * 2.0 ** min(attempt, 30), max_s)
