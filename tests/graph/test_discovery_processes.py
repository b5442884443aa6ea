"""Discovery: the graph snapshot, and what happens when participants die or are stopped."""

from __future__ import annotations

import os
import signal
import time

from dptpu.graph.discovery import get_graph


def _announcements(domain_dir):
    return sorted(p.name for p in domain_dir.glob("n-*.json"))


def _wait(condition, timeout=3.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


def test_graph_snapshot_lists_nodes_topics_and_services(spawn, domain_dir):
    server = spawn("param_node")
    listener = spawn("listener", "--timeout", "10")
    talker = spawn("talker", "--count", "1", "--wait-subs", "1", "--linger", "10")
    server.wait_event("ready")
    listener.wait_event("ready")
    talker.wait_event("published")
    assert _wait(lambda: "/param_node/toggle" in get_graph(directory=domain_dir).services)
    graph = get_graph(directory=domain_dir)
    assert [n.fully_qualified_name for n in graph.nodes] == ["/listener", "/param_node", "/talker"]
    chatter = graph.topics["/chatter"]
    assert (chatter.types, chatter.publisher_count, chatter.subscription_count) == (("std_msgs/msg/String",), 1, 1)
    assert chatter.publishers[0].qos.depth == 10 and chatter.publishers[0].node == "/talker"
    assert graph.services["/param_node/toggle"].types == ("std_srvs/srv/SetBool",)
    assert graph.services["/param_node/get_parameters"].types == ("rcl_interfaces/srv/GetParameters",)
    assert graph.services["/talker/list_parameters"].servers == ("/talker",)
    as_dict = graph.to_dict()
    assert as_dict["topics"]["/chatter"]["publisher_count"] == 1
    assert {n["pid"] for n in as_dict["nodes"]} == {server.proc.pid, listener.proc.pid, talker.proc.pid}


def test_publisher_killed_subscriber_keeps_running_and_reconnects_to_a_new_one(spawn, domain_dir):
    listener = spawn("listener", "--timeout", "15", "--idle", "3")
    listener.wait_event("ready")
    first = spawn("talker", "--name", "first", "--prefix", "a", "--count", "1000", "--period", "0.01",
                  "--wait-subs", "1")
    listener.wait_event("first")
    assert _wait(lambda: len(_announcements(domain_dir)) == 2)
    first.proc.send_signal(signal.SIGKILL)
    first.proc.wait(5)
    # the listener notices the dead pid and deletes the stale announcement (within about a second)
    assert _wait(lambda: len(_announcements(domain_dir)) == 1, timeout=3.0)
    assert listener.proc.poll() is None
    second = spawn("talker", "--name", "second", "--prefix", "b", "--count", "5", "--wait-subs", "1")
    assert second.wait_event("published")["count"] == 5
    received = listener.wait_event("done", timeout=10)["received"]
    assert received[-5:] == ["b0", "b1", "b2", "b3", "b4"]
    assert all(m.startswith("a") for m in received[:-5]) and len(received) > 5
    assert listener.wait() == 0


def test_subscriber_killed_publisher_and_other_subscribers_unaffected(spawn):
    doomed = spawn("listener", "--name", "doomed", "--timeout", "15")
    survivor = spawn("listener", "--name", "survivor", "--count", "150", "--timeout", "15")
    doomed.wait_event("ready")
    survivor.wait_event("ready")
    talker = spawn("talker", "--count", "150", "--period", "0.004", "--wait-subs", "2")
    doomed.wait_event("first")
    doomed.proc.send_signal(signal.SIGKILL)
    assert talker.wait_event("published")["count"] == 150
    assert survivor.wait_event("done")["received"] == [str(i) for i in range(150)]


def test_sigterm_stops_a_node_cleanly_and_withdraws_its_announcement(spawn, domain_dir):
    listener = spawn("listener", "--timeout", "30")
    listener.wait_event("ready")
    assert _wait(lambda: len(_announcements(domain_dir)) == 1)
    started = time.monotonic()
    listener.proc.send_signal(signal.SIGTERM)
    assert listener.wait(timeout=5) == 0, listener.stderr
    assert time.monotonic() - started < 2.0
    assert listener.wait_event("done")["received"] == []
    assert _announcements(domain_dir) == []
    assert os.listdir(domain_dir / "ep") == []
