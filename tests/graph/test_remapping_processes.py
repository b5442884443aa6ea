"""Remapping and namespaces across processes: a remapped topic reaches the right subscriber only."""

from __future__ import annotations

from dptpu.graph.discovery import get_graph


def test_remapped_topic_reaches_the_namespaced_subscriber(spawn, domain_dir):
    # listener subscribes to relative "talk" in namespace /robot -> /robot/talk
    right = spawn("listener", "--topic", "talk", "--count", "3", "--linger", "3", "--ros-args", "-r", "__ns:=/robot",
                  "-r", "__node:=ear")
    wrong = spawn("listener", "--name", "bystander", "--timeout", "5")  # /chatter (alive until the graph is read)
    assert right.wait_event("ready")["topic"] == "/robot/talk"
    assert wrong.wait_event("ready")["topic"] == "/chatter"
    talker = spawn("talker", "--count", "3", "--wait-subs", "1", "--ros-args", "-r", "chatter:=/robot/talk")
    assert talker.wait_event("ready")["topic"] == "/robot/talk"
    assert talker.wait_event("published")["count"] == 3  # it saw the subscription: both are announced
    graph = get_graph(directory=domain_dir)
    names = {node.fully_qualified_name for node in graph.nodes}
    assert {"/robot/ear", "/bystander", "/talker"} <= names
    assert graph.topics["/robot/talk"].publisher_count == 1
    assert graph.topics["/robot/talk"].subscription_count == 1
    assert right.wait_event("done")["received"] == ["0", "1", "2"]
    assert wrong.wait_event("done")["received"] == []
