"""The in-process node harness (nodes/harness.py): isolation, wiring, waiting, scan frames."""
from __future__ import annotations

import os

import numpy as np
import pytest

from dptpu.graph.interfaces import String
from dptpu.graph.node import Node
from dptpu.nodes.harness import NodeHarness, fringe_frames


class Echo(Node):
    """The smallest node with a parameter: republishes ``prefix + data`` from /in on /out."""

    def __init__(self, **node_options):
        super().__init__("echo", **node_options)
        self.prefix = self.declare_parameter("prefix", "").value
        self.publisher = self.create_publisher(String, "/out", 10)
        self.subscription = self.create_subscription(String, "/in", self.on_in, 10)

    def on_in(self, msg):
        if msg.data == "raise":
            raise RuntimeError("echo was asked to fail")
        self.publisher.publish(String(data=self.prefix + msg.data))


def test_messages_go_through_real_sockets_and_parameters_reach_the_node():
    with NodeHarness() as harness:
        node = harness.start(Echo, prefix="> ")
        source = harness.publisher(String, "/in")
        out = harness.collect(String, "/out")
        harness.connect()
        for text in ("a", "b", "c"):
            source.publish(String(data=text))
        assert [m.data for m in harness.wait(out, 3)] == ["> a", "> b", "> c"]
        assert node.subscription.received_count == 3  # received from the socket, not called directly


def test_a_callback_exception_fails_the_test_instead_of_being_logged():
    with NodeHarness() as harness:
        harness.start(Echo)
        source = harness.publisher(String, "/in")
        harness.collect(String, "/out")
        harness.connect()
        source.publish(String(data="raise"))
        with pytest.raises(RuntimeError, match="echo was asked to fail"):
            harness.spin_for(1.0)


def test_connect_names_the_topics_left_unconnected_and_wait_says_how_many_came():
    with NodeHarness() as harness:
        harness.start(Echo)
        harness.publisher(String, "/in_typo")
        with pytest.raises(TimeoutError, match="not connected within 0.3 s: /in_typo"):
            harness.connect(timeout_s=0.3)
    with NodeHarness() as harness:
        harness.start(Echo)
        out = harness.collect(String, "/out")
        harness.connect()
        with pytest.raises(TimeoutError, match="/out: 0 of 1 messages within 0.2 s"):
            harness.wait(out, 1, timeout_s=0.2)


def test_private_discovery_folder_is_made_and_the_environment_restored(monkeypatch):
    monkeypatch.setenv("DPTPU_DISCOVERY_DIR", "/tmp/somewhere-else")
    with NodeHarness() as harness:
        folder = os.environ["DPTPU_DISCOVERY_DIR"]
        assert folder != "/tmp/somewhere-else" and os.path.isdir(folder)
        harness.start(Echo)
        assert os.listdir(os.path.join(folder, f"domain-{harness.domain_id}"))  # the nodes announced themselves
    assert os.environ["DPTPU_DISCOVERY_DIR"] == "/tmp/somewhere-else" and not os.path.exists(folder)


def test_fringe_frames_number_the_patterns_of_a_scan():
    stacks = [np.zeros((4, 3, 5), np.uint8), np.ones((3, 3, 5), np.uint16)]
    frames = fringe_frames(stacks, [16.0, 1.0], sequence_id=9, stamp_ns=1000, frame_period_ns=10)
    triggers = [f.trigger for f in frames]
    assert [t.pattern_index for t in triggers] == list(range(7)) and {t.pattern_count for t in triggers} == {7}
    assert [(t.frequency, t.steps, t.step) for t in triggers[3:5]] == [(16.0, 4, 3), (1.0, 3, 0)]
    assert [f.image.encoding for f in frames[3:5]] == ["mono8", "mono16"]
    assert frames[6].image.header.stamp.to_ns() == 1060 and {t.sequence_id for t in triggers} == {9}
    with pytest.raises(ValueError, match="one frequency per stack; got 2 stacks and 1 frequencies"):
        fringe_frames(stacks, [16.0], sequence_id=1)
