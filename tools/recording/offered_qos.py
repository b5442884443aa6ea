"""The ``offered_qos_profiles`` an MCAP channel of the ``ros2`` profile carries: rosbag2's YAML of the QoS the
topic's publishers offered, which ``ros2 bag play`` publishes with (a latched topic stays latched on playback).

rosbag2 writes one list item per publisher; the recorder here subscribes with one profile matched to all of them
(:func:`dptpu.tools.recording.recorder.recording_qos`), so the list holds that one. The enum values are ROS 2's
``rmw_qos_*_policy_t`` numbers, as rosbag2 (Humble) writes them and later releases still read: history
``keep_last`` 1, ``keep_all`` 2; reliability ``reliable`` 1, ``best_effort`` 2; durability ``transient_local`` 1,
``volatile`` 2; liveliness ``automatic`` 1; deadline, lifespan and lease duration infinite
(``2147483647 s 4294967295 ns``, rosbag2's spelling of ``RMW_DURATION_INFINITE``).
"""
from __future__ import annotations

from collections.abc import Mapping

__all__ = ["DEFAULT_OFFERED_QOS", "offered_qos_profiles"]

_HISTORY = {"keep_last": 1, "keep_all": 2}
_RELIABILITY = {"reliable": 1, "best_effort": 2}
_DURABILITY = {"transient_local": 1, "volatile": 2}
_INFINITE = "\n    sec: 2147483647\n    nsec: 4294967295"
#: What a channel is said to have been offered when nothing is known: ROS 2's default profile.
DEFAULT_OFFERED_QOS = {"history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile"}


def offered_qos_profiles(profile: Mapping = DEFAULT_OFFERED_QOS) -> str:
    """rosbag2's YAML of one offered profile (a list of one item).

    Parameters
    ----------
    profile : mapping
        ``history`` (``keep_last`` or ``keep_all``), ``depth``, ``reliability`` (``reliable`` or ``best_effort``),
        ``durability`` (``transient_local`` or ``volatile``), as ``QoSProfile.to_dict()`` gives them.

    Raises
    ------
    ValueError
        A policy value outside those, naming it.
    """
    values = []
    for key, table in (("history", _HISTORY), ("reliability", _RELIABILITY), ("durability", _DURABILITY)):
        value = str(profile.get(key, DEFAULT_OFFERED_QOS[key])).lower()
        if value not in table:
            raise ValueError(f"QoS {key} must be one of {', '.join(table)}; got {value!r}")
        values.append(table[value])
    depth = int(profile.get("depth", 0))
    if depth < 0:
        raise ValueError(f"QoS depth must be >= 0; got {depth}")
    history, reliability, durability = values
    return (f"- history: {history}\n  depth: {depth}\n  reliability: {reliability}\n  durability: {durability}\n"
            f"  deadline:{_INFINITE}\n  lifespan:{_INFINITE}\n  liveliness: 1\n"
            f"  liveliness_lease_duration:{_INFINITE}\n  avoid_ros_namespace_conventions: false\n")
