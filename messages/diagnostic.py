"""Diagnostics: ``diagnostic_msgs/msg/KeyValue``, ``DiagnosticStatus`` and ``DiagnosticArray`` (ROS 2 fields).

What a ROS 2 robot's ``/diagnostics`` carries (the ``diagnostic_aggregator`` and ``rqt_robot_monitor`` read it):
one array per publication, one status per component, each with a level, a name, a human message, the hardware it
is about, and key-value pairs of figures. The scanner publishes one array per scan (``nodes/scan_monitor``).
"""

from __future__ import annotations

from .schema import Message, message, nested, nested_list, scalar
from .std import Header

__all__ = ["KeyValue", "DiagnosticStatus", "DiagnosticArray"]


@message("diagnostic_msgs/msg/KeyValue", version=1)
class KeyValue(Message):
    """One named figure of a status, ROS 2 ``diagnostic_msgs/msg/KeyValue``.

    Attributes
    ----------
    key : str
        What the value is, with its unit where it has one (``"latency_ms"``).
    value : str
        The value as text.
    """

    key: str = scalar("string")
    value: str = scalar("string")


@message("diagnostic_msgs/msg/DiagnosticStatus", version=1)
class DiagnosticStatus(Message):
    """The state of one component, ROS 2 ``diagnostic_msgs/msg/DiagnosticStatus``.

    Attributes
    ----------
    level : int
        ``OK = 0``, ``WARN = 1``, ``ERROR = 2``, ``STALE = 3`` (a ``byte`` in ROS 2, uint8 here).
    name : str
        The component, e.g. ``"dptpu: scan"`` (the aggregator groups by the part before ``:``).
    message : str
        A human description of the state.
    hardware_id : str
        The device the status is about (empty when none).
    values : list of KeyValue
        Figures of the state.
    """

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3

    level: int = scalar("uint8")
    name: str = scalar("string")
    message: str = scalar("string")
    hardware_id: str = scalar("string")
    values: list = nested_list(KeyValue)

    def check_consistency(self) -> None:
        if self.level > self.STALE:
            raise ValueError(f"DiagnosticStatus.level must be OK (0), WARN (1), ERROR (2) or STALE (3); "
                             f"got {self.level}")


@message("diagnostic_msgs/msg/DiagnosticArray", version=1)
class DiagnosticArray(Message):
    """Statuses published together, ROS 2 ``diagnostic_msgs/msg/DiagnosticArray``.

    Attributes
    ----------
    header : Header
        When the statuses were made.
    status : list of DiagnosticStatus
    """

    header: Header = nested(Header)
    status: list = nested_list(DiagnosticStatus)
