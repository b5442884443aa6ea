"""The scan monitor's ``/diagnostics``: one ``diagnostic_msgs/DiagnosticArray`` per reported scan (pure logic).

A ROS 2 robot watches its devices on ``/diagnostics`` (``diagnostic_aggregator``, ``rqt_robot_monitor``); the
scanner's array holds:

- ``dptpu: scan``: the scan's verdict as the monitor's line gives it. Level ``OK`` for ``ok``, ``WARN`` for
  ``UNTRUSTED`` (a cloud came, but beyond the monitor's bounds), ``ERROR`` for ``FAILED`` and ``LOST``; the message
  is the line; values: every figure of the scan's record (``sequence_id``, ``outcome``, ``valid_points``,
  ``wrong_share``, ``completeness``, ``latency_ms``, ...), numbers as text;
- ``dptpu: <node>`` (``dptpu: /phase``, ``dptpu: /cloud``, ...): the latest ``ScanStatus`` of each processing node,
  its level (ScanStatus shares DiagnosticStatus's levels), its reason (or its state when it has none) and its counts.

``hardware_id`` is the monitor's ``hardware_id`` parameter (the scanner's serial number on a real rig).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping

from dptpu.messages import DiagnosticArray, DiagnosticStatus, Header, KeyValue, ScanStatus, Time

__all__ = ["OUTCOME_LEVELS", "SCAN_STATUS_NAME", "scan_diagnostics"]

SCAN_STATUS_NAME = "dptpu: scan"
#: Diagnostic level of each outcome of the monitor.
OUTCOME_LEVELS = {"ok": DiagnosticStatus.OK, "untrusted": DiagnosticStatus.WARN, "failed": DiagnosticStatus.ERROR,
                  "lost": DiagnosticStatus.ERROR}
_STATUS_COUNTS = ("state", "frames_expected", "frames_received", "frames_dropped", "decode_errors", "valid_pixels",
                  "total_pixels", "duration_s")


def scan_diagnostics(record: Mapping, line: str, node_statuses: Iterable[ScanStatus], *, stamp: Time,
                     hardware_id: str = "") -> DiagnosticArray:
    """The DiagnosticArray of one reported scan.

    Parameters
    ----------
    record : mapping
        The monitor's record of the scan (``sequence_id``, ``outcome`` and its figures).
    line : str
        The monitor's line of the scan (the scan status's message).
    node_statuses : iterable of ScanStatus
        The latest status of each node, one each.
    stamp : Time
        The array's header stamp (now).
    hardware_id : str
        The scanner's id, in every status.
    """
    values = [KeyValue(key=str(key), value=_text(value)) for key, value in record.items()
              if not isinstance(value, dict)]
    statuses = [DiagnosticStatus(level=OUTCOME_LEVELS[record["outcome"]], name=SCAN_STATUS_NAME, message=line,
                                 hardware_id=hardware_id, values=values)]
    for status in node_statuses:
        counts = [KeyValue(key="sequence_id", value=str(status.sequence_id))]
        counts += [KeyValue(key=key, value=_text(getattr(status, key))) for key in _STATUS_COUNTS]
        # ScanStatus's levels are DiagnosticStatus's (OK 0, WARN 1, ERROR 2, STALE 3)
        statuses.append(DiagnosticStatus(level=min(int(status.level), DiagnosticStatus.STALE),
                                         name=f"dptpu: {status.node}", message=status.reason or status.state,
                                         hardware_id=hardware_id, values=counts))
    return DiagnosticArray(header=Header(stamp=stamp), status=statuses)


def _text(value) -> str:
    """A figure as text: floats with 6 significant digits, but every integer digit and 3 decimals from 1e5 up (a
    Unix time in seconds stays to the millisecond, not ``1.79574e+09``), the rest as ``str``."""
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) >= 1e5 else f"{value:.6g}"
    return str(value)

