"""Fixtures of the launch tests: writing launch files, and running ``dptpu launch`` as a real process."""
from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[3]
FIXTURES = "tests.tools.launch.fixtures"
TICKER = f"{FIXTURES}.ticker"
CRASHER = f"{FIXTURES}.crasher"
STUBBORN = f"{FIXTURES}.stubborn"


@pytest.fixture
def write_file(tmp_path):
    """Factory: ``write_file("name.yaml", text)`` writes dedented ``text`` under ``tmp_path``; returns the path."""

    def write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
        return path

    return write


def launcher_env(**extra: str) -> dict[str, str]:
    """The environment for a launcher subprocess: the repository importable from any child."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), env.get("PYTHONPATH", "")]))
    env.update(extra)
    return env


def process_running(pid: int) -> bool:
    """True when ``pid`` exists and is not a zombie (read from /proc, else os.kill(pid, 0))."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True
    return stat[stat.rfind(")") + 2] not in "ZX"


class LaunchProcess:
    """``python -m dptpu.cli.main launch FILE ARGS...`` running in its own session, output collected by threads.

    ``wait_for(pattern)`` blocks until a line of stdout or stderr matches and returns the match;
    ``pids()`` lists every node pid the launcher reported starting. ``kill_everything()`` is the
    safety net of the finally blocks: SIGKILL to the launcher and to every node group it reported.
    """

    def __init__(self, path: Path, *args: str, env: dict[str, str] | None = None):
        self.lines: list[str] = []
        self._new_lines: queue.Queue[str] = queue.Queue()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "dptpu.cli.main", "launch", str(path), *args], cwd=REPO_ROOT,
            env=env or launcher_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
        self._readers = [threading.Thread(target=self._read, args=(pipe,), daemon=True)
                         for pipe in (self.process.stdout, self.process.stderr)]
        for reader in self._readers:
            reader.start()

    def _read(self, pipe) -> None:
        for raw in iter(pipe.readline, b""):
            line = raw.decode("utf-8", errors="replace").rstrip("\n")
            self.lines.append(line)
            self._new_lines.put(line)

    def wait_for(self, pattern: str, timeout_s: float = 15.0) -> re.Match:
        regex = re.compile(pattern)
        for line in list(self.lines):
            match = regex.search(line)
            if match:
                return match
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                line = self._new_lines.get(timeout=0.05)
            except queue.Empty:
                continue
            match = regex.search(line)
            if match:
                return match
        raise AssertionError(f"no line matched {pattern!r} within {timeout_s} s; output:\n" + "\n".join(self.lines))

    def wait_for_all(self, pattern: str, timeout_s: float = 15.0) -> list[re.Match]:
        """Every line matching ``pattern`` once the launcher has exited (waits for it)."""
        self.process.wait(timeout=timeout_s)
        for reader in self._readers:
            reader.join(timeout=2.0)
        regex = re.compile(pattern)
        return [match for match in map(regex.search, self.lines) if match]

    def pids(self) -> list[int]:
        return [int(match.group(1)) for match in map(re.compile(r"^\[launch\] started '.*' \(pid (\d+)\)").search,
                                                      list(self.lines)) if match]

    def finish(self, timeout_s: float) -> int:
        """Wait for the launcher to exit and its output to be read; returns its exit code."""
        code = self.process.wait(timeout=timeout_s)
        for reader in self._readers:
            reader.join(timeout=2.0)
        return code

    def kill_everything(self, extra_pids: tuple[int, ...] = ()) -> None:
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait(timeout=5)
        for pid in [*self.pids(), *extra_pids]:
            for kill in (os.killpg, os.kill):
                try:
                    kill(pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
