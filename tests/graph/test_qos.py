"""QoS profiles: shorthand, presets, the ROS 2 compatibility rules, and what they mean for queues and pipes."""

from __future__ import annotations

import time

import pytest

from dptpu.graph import (
    DurabilityPolicy,
    HistoryPolicy,
    InvalidQoSProfileException,
    Node,
    QoSProfile,
    ReliabilityPolicy,
    SingleThreadedExecutor,
    String,
    qos_profile_sensor_data,
    qos_profile_system_default,
)
from dptpu.graph.qos import (
    KEEP_ALL_QUEUE_LIMIT,
    RELIABLE_PIPE_MESSAGES,
    as_qos_profile,
    pipe_high_water_mark,
    qos_compatibility,
    queue_limit,
)


def test_int_shorthand_becomes_a_profile_at_once():
    qos = as_qos_profile(7)
    assert (qos.history, qos.depth, qos.reliability, qos.durability) == (
        HistoryPolicy.KEEP_LAST, 7, ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    with pytest.raises(InvalidQoSProfileException, match="QoSProfile or an int depth"):
        as_qos_profile("10")
    with pytest.raises(InvalidQoSProfileException, match="depth must be an int >= 0"):
        QoSProfile(depth=-1)


def test_presets_and_resolution():
    assert (qos_profile_sensor_data.depth, qos_profile_sensor_data.reliability) == (5, ReliabilityPolicy.BEST_EFFORT)
    resolved = qos_profile_system_default.resolved()
    assert (resolved.history, resolved.depth, resolved.reliability, resolved.durability) == (
        HistoryPolicy.KEEP_LAST, 10, ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    assert QoSProfile.from_dict(qos_profile_sensor_data.to_dict()) == qos_profile_sensor_data


def test_queue_and_pipe_sizes():
    assert queue_limit(QoSProfile(depth=3)) == 3
    assert queue_limit(QoSProfile(history=HistoryPolicy.KEEP_ALL)) == KEEP_ALL_QUEUE_LIMIT
    # twice what a pipe must absorb: libzmq's writer learns of reads only every hwm/2 messages
    assert pipe_high_water_mark(QoSProfile(depth=3)) == 2 * RELIABLE_PIPE_MESSAGES
    assert pipe_high_water_mark(QoSProfile(depth=3, reliability=ReliabilityPolicy.BEST_EFFORT)) == 6
    assert pipe_high_water_mark(QoSProfile(depth=500)) == 1000


def test_compatibility_follows_ros2_request_versus_offered():
    reliable, best_effort = QoSProfile(), QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT)
    transient = QoSProfile(durability=DurabilityPolicy.TRANSIENT_LOCAL)
    assert qos_compatibility(reliable, best_effort) is None
    assert qos_compatibility(transient, reliable) is None
    assert "requests RELIABLE" in qos_compatibility(best_effort, reliable)
    assert "requests TRANSIENT_LOCAL" in qos_compatibility(reliable, transient)


def _spin_until(executor, condition, timeout=3.0):
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return condition()


def test_best_effort_publisher_does_not_reach_reliable_subscription(context):
    node = Node("qos_check", context=context)
    got_reliable, got_best_effort = [], []
    node.create_subscription(String, "scan", lambda m: got_reliable.append(m.data), 10)
    node.create_subscription(String, "scan", lambda m: got_best_effort.append(m.data), qos_profile_sensor_data)
    publisher = node.create_publisher(String, "scan", qos_profile_sensor_data)
    assert publisher.wait_for_subscriptions(1, timeout_sec=3.0)
    publisher.publish(String(data="x"))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    assert _spin_until(executor, lambda: got_best_effort == ["x"])
    executor.spin_once(timeout_sec=0.2)
    assert got_reliable == []
    assert publisher.get_subscription_count() == 1
