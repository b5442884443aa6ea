"""Fixtures of the scanner node tests: node modules run as real processes, and an in-process probe node.

Every test gets a private discovery folder and domain (as in ``tests/graph``), so it never meets another
test's nodes or a real graph. ``spawn_node("dptpu.nodes.projector", "--ros-args", "-p", "port:=...")``
runs ``python -m dptpu.nodes.projector ...``; every process started is killed at the end. ``probe`` is a
node in the test process whose executor spins on a background thread: its subscriptions collect
messages that arrived over real ZeroMQ sockets from the node processes.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from tests.graph.conftest import NodeProcess, private_domain_env

REPO_ROOT = Path(__file__).resolve().parents[2]
TEST_DOMAIN_ID = 23


@pytest.fixture
def node_env(monkeypatch):
    """Environment of a private domain, set for child processes and this process alike."""
    yield from private_domain_env(monkeypatch, "dn", TEST_DOMAIN_ID)


@pytest.fixture
def spawn_node(node_env):
    """``spawn_node(module, *args, env=None)``: ``python -m module *args`` in the private domain."""
    started: list[NodeProcess] = []

    def start(module: str, *args: str, env: dict | None = None) -> NodeProcess:
        full_env = dict(os.environ)
        full_env.update(node_env)
        full_env["PYTHONPATH"] = str(REPO_ROOT) + os.pathsep + full_env.get("PYTHONPATH", "")
        full_env["PYTHONUNBUFFERED"] = "1"
        full_env.update(env or {})
        process = NodeProcess(["-m", module, *args], full_env)
        started.append(process)
        return process

    yield start
    for process in started:
        process.terminate()
    for process in started:
        try:
            process.proc.wait(timeout=5)
        except Exception:  # noqa: BLE001 -- killed below
            pass
        process.kill()


class Inbox:
    """Messages of one subscription, in arrival order; ``wait(count, timeout)`` blocks until enough arrived."""

    def __init__(self):
        self.messages: list = []
        self._cond = threading.Condition()
        self.subscription = None  # set by Probe.subscribe

    def wait_for_publishers(self, count: int = 1, timeout: float = 10.0) -> None:
        """Block until the subscription is connected to ``count`` publishers (a message published before that
        is lost, as in ROS 2 with a volatile subscription); AssertionError after ``timeout``."""
        deadline = time.monotonic() + timeout
        while self.subscription.get_publisher_count() < count:
            if time.monotonic() > deadline:
                connected = self.subscription.get_publisher_count()
                raise AssertionError(f"{self.subscription.topic_name}: connected to {connected} of {count} "
                                     f"publisher(s) after {timeout} s")
            time.sleep(0.01)

    def __call__(self, msg) -> None:
        with self._cond:
            self.messages.append(msg)
            self._cond.notify_all()

    def wait(self, count: int = 1, timeout: float = 10.0) -> list:
        """The first ``count`` messages; AssertionError naming what arrived when they do not come in time."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while len(self.messages) < count:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise AssertionError(f"only {len(self.messages)} of {count} messages within {timeout} s: "
                                         f"{self.messages[-3:]}")
                self._cond.wait(remaining)
            return list(self.messages[:count])

    def wait_for(self, predicate, timeout: float = 10.0):
        """The first message for which ``predicate(msg)`` is true."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for msg in self.messages:
                    if predicate(msg):
                        return msg
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise AssertionError(f"no matching message within {timeout} s among {len(self.messages)}: "
                                         f"{self.messages[-3:]}")
                self._cond.wait(remaining)


class Probe:
    """A test-side node spun on a background thread: ``subscribe`` returns an :class:`Inbox`."""

    def __init__(self, domain_id: int):
        from dptpu.graph import Context, Node
        from dptpu.graph.executors import SingleThreadedExecutor

        self.context = Context()
        self.context.init([], domain_id=domain_id)
        self.node = Node("probe", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def subscribe(self, msg_type, topic: str, qos=100) -> Inbox:
        inbox = Inbox()
        inbox.subscription = self.node.create_subscription(msg_type, topic, inbox, qos)
        return inbox

    def publisher(self, msg_type, topic: str, qos=100):
        return self.node.create_publisher(msg_type, topic, qos)

    def client(self, srv_type, name: str):
        return self.node.create_client(srv_type, name)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.context.try_shutdown()
        self._thread.join(timeout=2.0)


@pytest.fixture
def probe(node_env):
    """An in-process node of the private domain (see :class:`Probe`)."""
    node = Probe(TEST_DOMAIN_ID)
    yield node
    node.close()
