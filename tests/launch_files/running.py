"""Run ``dptpu launch FILE`` as a real process and follow its output line by line (whole-graph tests).

``LaunchRun`` starts the launcher with the test's private discovery folder and domain (the ``node_env``
fixture), collects every output line on a thread, and parses what the tests need: the launcher's
``started 'NAME' (pid N)`` lines (to kill or measure a node) and the scan monitor's per-scan lines.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
SIM_RIG = REPO_ROOT / "launch" / "sim_rig.yaml"
#: the round-number twin rig the whole-graph tests render with (sim_rig.yaml's default is the shipped renders' rig)
TWIN_RIG_ARG = f"rig:={REPO_ROOT / 'launch' / 'params' / 'twin_rig.yaml'}"
_STARTED = re.compile(r"\[launch\] started '([^']+)' \(pid (\d+)\)")
_SCAN = re.compile(r"^\[scan_monitor\] scan (\d+)(?: (\S+))?: (ok|UNTRUSTED|FAILED|LOST)")


class LaunchRun:
    """``dptpu launch FILE ARGS`` in the background; ``lines`` holds its stdout and stderr as they come."""

    def __init__(self, launch_file, *args: str, env: dict, cwd):
        full_env = dict(os.environ)
        full_env.update(env)
        full_env["PYTHONPATH"] = str(REPO_ROOT) + os.pathsep + full_env.get("PYTHONPATH", "")
        command = [sys.executable, "-c", "import sys; from dptpu.cli.main import main; sys.exit(main())",
                   "launch", str(launch_file), *args]
        self.proc_env = full_env
        self.proc = subprocess.Popen(command, cwd=cwd, env=full_env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, bufsize=1)
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self._cond:
                self.lines.append(line.rstrip("\n"))
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def text(self, last: int = 60) -> str:
        with self._cond:
            return "\n".join(self.lines[-last:])

    def wait_for(self, predicate, timeout: float, what: str):
        """Block until ``predicate(lines)`` gives a true value (returned); AssertionError with the output tail."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                value = predicate(self.lines)
                if value:
                    return value
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (self.proc.poll() is not None and not self._reader.is_alive()):
                    raise AssertionError(f"{what}: not seen within {timeout} s (exit {self.proc.poll()}); output:\n"
                                         + "\n".join(self.lines[-60:]))
                self._cond.wait(min(remaining, 0.5))

    def pids(self, name: str) -> list[int]:
        """Every pid the launcher reported for node ``name`` (respawns append)."""
        with self._cond:
            return [int(m.group(2)) for m in map(_STARTED.search, self.lines) if m and m.group(1) == name]

    def scans(self) -> list[tuple[int, str, str, str]]:
        """The monitor's scan lines: ``(sequence_id, scene, outcome, line)``."""
        with self._cond:
            return [(int(m.group(1)), m.group(2) or "", m.group(3), line)
                    for line in self.lines if (m := _SCAN.match(line))]

    def wait(self, timeout: float) -> int:
        try:
            code = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"the launch did not end within {timeout} s; output:\n{self.text()}") from None
        self._reader.join(timeout=5)
        return code

    def interrupt(self) -> None:
        """Ctrl-C to the launcher (clean shutdown of every node)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)

    def close(self) -> None:
        """Stop the launch (Ctrl-C, then kill) and every node process it reported."""
        self.interrupt()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=5)
        for m in map(_STARTED.search, list(self.lines)):
            if m:
                try:
                    os.killpg(int(m.group(2)), signal.SIGKILL)  # each node runs in its own process group
                except (ProcessLookupError, PermissionError):
                    pass


def rss_kib(pid: int) -> int:
    """Resident memory of process ``pid`` in KiB (``VmRSS`` of ``/proc/PID/status``); 0 when it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except (FileNotFoundError, ProcessLookupError):
        pass
    return 0
