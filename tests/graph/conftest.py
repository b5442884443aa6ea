"""Fixtures for the graph tests: a private discovery folder per test, node processes that are always killed.

Every test gets its own discovery folder (a short path under /tmp, so ipc socket paths fit) and
domain, set both for child processes and, through ``monkeypatch``, for nodes created in the test
process itself: tests never see each other's nodes, nor any real graph on the machine.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

NODES_DIR = Path(__file__).parent / "nodes"
REPO_ROOT = Path(__file__).resolve().parents[2]
TEST_DOMAIN_ID = 17


class NodeProcess:
    """A node script run as its own process; its JSON stdout lines become events."""

    def __init__(self, args, env):
        self.args = args
        self.proc = subprocess.Popen([sys.executable, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     env=env, text=True, cwd=str(REPO_ROOT))
        self._events: queue.Queue = queue.Queue()
        self.events: list[dict] = []
        self.stderr_lines: list[str] = []
        self._readers = [threading.Thread(target=self._read_stdout, daemon=True),
                         threading.Thread(target=self._read_stderr, daemon=True)]
        for reader in self._readers:
            reader.start()

    def _read_stdout(self):
        for line in self.proc.stdout:
            line = line.strip()
            if not line:
                continue
            try:
                self._events.put(json.loads(line))
            except ValueError:
                self._events.put({"event": "text", "text": line})

    def _read_stderr(self):
        for line in self.proc.stderr:
            self.stderr_lines.append(line.rstrip("\n"))

    @property
    def stderr(self) -> str:
        return "\n".join(self.stderr_lines)

    def wait_event(self, name: str, timeout: float = 10.0) -> dict:
        """The next event called ``name`` (earlier ones are kept in ``events``)."""
        for event in self.events:
            if event.get("event") == name and not event.get("_taken"):
                event["_taken"] = True
                return event
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"{self.args[0]}: no {name!r} event within {timeout} s; events {self.events}; "
                                     f"exit code {self.proc.poll()}; stderr:\n{self.stderr}")
            try:
                event = self._events.get(timeout=min(remaining, 0.1))
            except queue.Empty:
                continue
            self.events.append(event)
            if event.get("event") == name:
                event["_taken"] = True
                return event

    def wait_for_stderr(self, text: str, timeout: float = 5.0) -> bool:
        """Whether ``text`` appears in the process's stderr within ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.stderr:
                return True
            time.sleep(0.02)
        return text in self.stderr

    def wait(self, timeout: float = 10.0) -> int:
        """The exit code, once the process has exited and its stdout and stderr are read to the end."""
        try:
            code = self.proc.wait(timeout=timeout)
            for reader in self._readers:  # the pipes close at exit: the readers finish
                reader.join(timeout=5.0)
            return code
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f"{self.args[0]} did not exit within {timeout} s; stderr:\n{self.stderr}") from None

    def terminate(self):
        if self.proc.poll() is None:
            self.proc.terminate()

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            pass


def private_domain_env(monkeypatch, prefix: str, domain_id: int):
    """Generator for fixtures: a fresh discovery folder and ``domain_id``, set for child processes and this process
    alike, with every other graph variable unset; yields the values and removes the folder afterwards."""
    folder = tempfile.mkdtemp(prefix=prefix, dir="/tmp")
    values = {"DPTPU_DISCOVERY_DIR": folder, "DPTPU_DOMAIN_ID": str(domain_id)}
    for name in ("ROS_DOMAIN_ID", "DPTPU_TRANSPORT", "DPTPU_TCP_INTERFACE", "DPTPU_CURVE_SECRET_KEY",
                 "DPTPU_CURVE_AUTHORIZED_KEYS", "DPTPU_CURVE", "DPTPU_PEERS", "DPTPU_DISCOVERY_PORT"):
        monkeypatch.delenv(name, raising=False)
    for name, value in values.items():
        monkeypatch.setenv(name, value)
    yield values
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture
def graph_env(monkeypatch):
    """Environment of a private domain: ``{"DPTPU_DISCOVERY_DIR": ..., "DPTPU_DOMAIN_ID": ...}``."""
    yield from private_domain_env(monkeypatch, "dg", TEST_DOMAIN_ID)


@pytest.fixture
def domain_dir(graph_env) -> Path:
    return Path(graph_env["DPTPU_DISCOVERY_DIR"]) / f"domain-{TEST_DOMAIN_ID}"


@pytest.fixture
def spawn(graph_env):
    """``spawn("talker", "--count", "5", env={...})`` runs ``tests/graph/nodes/talker.py``; all are killed at the
    end."""
    started: list[NodeProcess] = []

    def start(script: str, *args, env=None) -> NodeProcess:
        full_env = dict(os.environ)
        full_env.update(graph_env)
        full_env["PYTHONPATH"] = str(REPO_ROOT) + os.pathsep + full_env.get("PYTHONPATH", "")
        full_env.update(env or {})
        process = NodeProcess([str(NODES_DIR / f"{script}.py"), *args], full_env)
        started.append(process)
        return process

    yield start
    for process in started:
        process.kill()


@pytest.fixture
def context(graph_env):
    """An initialized in-process :class:`dptpu.graph.Context` of the private domain, shut down at the end."""
    from dptpu.graph import Context

    ctx = Context()
    ctx.init(domain_id=TEST_DOMAIN_ID)
    yield ctx
    ctx.try_shutdown()


@pytest.fixture
def make_context(graph_env):
    """``make_context(args)``: a Context initialized with ROS arguments ``args``; all shut down at the end."""
    from dptpu.graph import Context

    made = []

    def make(args=None):
        ctx = Context()
        ctx.init(args, domain_id=TEST_DOMAIN_ID)
        made.append(ctx)
        return ctx

    yield make
    for ctx in made:
        ctx.try_shutdown()
