"""Known publishers (``dptpu.graph.known_publishers``): a configuration topic taken only from the node that owns
it, a conflicting second publisher refused and logged. The policy's rules on announcement entries, then real
publisher processes (``tests/graph/nodes/talker.py``) against an in-process subscription."""

from __future__ import annotations

import time

import pytest

from dptpu.graph import DurabilityPolicy, Node, QoSProfile, SingleThreadedExecutor, String
from dptpu.graph.known_publishers import SOLE_PUBLISHER, KnownPublishers, select_publishers

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _entry(fqn: str, pid: int, start_time: float) -> tuple:
    entry = {"fqn": fqn, "pid": pid, "start_time": start_time, "gid": f"{pid:032x}"}
    return entry, {"topic": "/t", "gid": f"p{pid}"}


def test_sole_takes_the_oldest_node_and_refuses_the_others_with_the_reason():
    owner, intruder = _entry("/projector", 10, 100.0), _entry("/intruder", 11, 200.0)
    accepted, refused = select_publishers([intruder, owner], SOLE_PUBLISHER)
    assert accepted == [owner]
    assert [(r[0]["fqn"], "/projector (pid 10) publishes it already" in r[2]) for r in refused] == [("/intruder", True)]


def test_named_nodes_only_and_a_second_node_of_the_same_name_refused():
    owner, twin, other = _entry("/sim", 10, 100.0), _entry("/sim", 12, 300.0), _entry("/cloud", 11, 50.0)
    accepted, refused = select_publishers([twin, other, owner], KnownPublishers(nodes=("/sim",)))
    assert accepted == [owner]
    reasons = {r[0]["pid"]: r[2] for r in refused}
    assert "not among the publishers it takes (/sim)" in reasons[11]
    assert "a second node named /sim (pid 12)" in reasons[12]
    assert select_publishers([twin, owner], None) == ([twin, owner], [])


def test_node_names_must_be_a_tuple():
    with pytest.raises(ValueError, match="tuple of node names"):
        KnownPublishers(nodes="/projector")


def _collect(context, node: Node, inbox: list, until, timeout: float) -> None:
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout
    while not until() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    executor.remove_node(node)


def test_second_publisher_of_a_configuration_topic_is_refused_and_logged(spawn, context, capfd):
    args = ("--topic", "/projector/pattern_sequence", "--count", "600", "--period", "0.05", "--linger", "0")
    owner = spawn("talker", "--name", "projector", "--prefix", "owner-", *args)
    owner.wait_event("ready")
    intruder = spawn("talker", "--name", "intruder", "--prefix", "forged-", *args)
    intruder.wait_event("ready")
    node = Node("phase", context=context)
    sole: list = []
    named: list = []
    anyone: list = []
    sole_sub = node.create_subscription(String, "/projector/pattern_sequence", lambda m: sole.append(m.data), 100,
                                        publishers=SOLE_PUBLISHER)
    node.create_subscription(String, "/projector/pattern_sequence", lambda m: named.append(m.data), 100,
                             publishers=KnownPublishers(nodes=("projector",)))  # relative: in the node's namespace

    def prefixes(inbox: list) -> set:
        return {text.split("-")[0] for text in inbox}

    node.create_subscription(String, "/projector/pattern_sequence", lambda m: anyone.append(m.data), 100)
    _collect(context, node, anyone, lambda: prefixes(anyone) == {"owner", "forged"} and len(sole) >= 5
             and len(named) >= 5, 15.0)
    assert prefixes(anyone) == {"owner", "forged"}  # without a policy both reach the subscription (the finding)
    assert prefixes(sole) == {"owner"} and prefixes(named) == {"owner"}
    assert sole_sub.get_publisher_count() == 1
    refusals = [line for line in capfd.readouterr().err.splitlines() if "refusing the publisher" in line]
    assert any("of node /intruder" in text and "/projector (pid" in text for text in refusals), refusals
    assert any("of node /intruder" in text and "not among the publishers it takes (/projector)" in text
               for text in refusals), refusals
    # the owner gone, the intruder is the oldest live publisher: the sole policy takes it, the named one does not
    owner.kill()
    taken = len(sole)
    _collect(context, node, sole, lambda: "forged" in prefixes(sole[taken:]), 15.0)
    assert "forged" in prefixes(sole[taken:])
    named_after = len(named)
    _collect(context, node, named, lambda: False, 0.5)
    assert prefixes(named[named_after:]) <= {"owner"}
