"""The plumbing the scanner's nodes share: topic QoS, the default optical frame, ScanStatus reports, back-off.

Each process subpackage (``dptpu.nodes.phase``, ``...cloud``, ...) takes these from here rather than from another
node's modules, so no node borrows a helper of another.

- :data:`DEFAULT_FRAME_ID`: the camera optical frame of frames, clouds and depth images (docs/messages.md).
- :data:`STATUS_QOS`, :data:`LATCHED_QOS`: the ``/scanner/status`` publishers of the processing nodes (one
  report a scan; deep enough for a burst of failed scans) and the transient-local topics that keep their last
  message for late joiners (``/camera/camera_info``, ``/projector/pattern_sequence``).
- :func:`scan_status`: one :class:`~dptpu.messages.ScanStatus` from a node, stamped now and named after it.
- :class:`DecodeErrorCount`: the messages a node's subscriptions could not decode since its last report (the
  ``decode_errors`` field of each ScanStatus).
- :func:`backoff_delay_s`: the reconnection back-off of the links to hardware (the projector's serial port, the
  camera).
"""
from __future__ import annotations

from dptpu.graph.node import Node
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import Header, ScanStatus, Time

__all__ = ["DEFAULT_FRAME_ID", "LATCHED_QOS", "STATUS_QOS", "DecodeErrorCount", "backoff_delay_s", "scan_status"]

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
