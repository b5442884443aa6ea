"""One answer to "does process PID still run" for discovery, shared memory and the launcher (graph/processes.py).

Discovery and shared memory each had their own ``kill(pid, 0)``, which calls a zombie alive: a node that exited but
was not yet reaped kept its announcement (and a peer its mapping) until the parent waited for it.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time

from dptpu.graph.discovery import entry_is_alive, host_identity
from dptpu.graph.processes import process_alive, process_start_ticks


def _wait_for_zombie(pid: int, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with open(f"/proc/{pid}/stat") as handle:
            if handle.read().rsplit(")", 1)[1].split()[0] == "Z":
                return
        time.sleep(0.02)
    raise AssertionError(f"process {pid} did not exit within {timeout_s} s")


def test_a_running_process_is_alive_an_exited_unreaped_one_is_not():
    child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    try:
        assert process_alive(child.pid) and process_alive(os.getpid())
        start = process_start_ticks(child.pid)
        assert start is not None and start >= process_start_ticks(os.getpid())
        host, boot_id = host_identity()
        entry = {"pid": child.pid, "pid_start": start, "host": host, "boot_id": boot_id}
        assert entry_is_alive(entry, host, boot_id)
        child.stdin.close()
        _wait_for_zombie(child.pid)  # exited, not yet reaped: os.kill(pid, 0) still succeeds
        os.kill(child.pid, 0)
        assert not process_alive(child.pid)
        assert not entry_is_alive(entry, host, boot_id)  # its announcement is stale at once
    finally:
        child.wait(timeout=30)
    assert not process_alive(child.pid) and process_start_ticks(child.pid) is None
    assert not process_alive(-1)
