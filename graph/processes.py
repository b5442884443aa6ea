"""Whether a process of this host still runs: :func:`process_alive`, the one answer the runtime and its tools use.

Discovery drops the announcement of a node whose process is gone (or whose pid a new process took:
:func:`process_start_ticks`), shared memory unmaps a peer's segment once its
writer is gone, the launcher waits for a node's process group to empty: each asks the same question. On Linux the
answer comes from ``/proc/PID/stat`` (a zombie, a process that exited but was not yet reaped by its parent, is
gone); elsewhere from ``kill(pid, 0)`` (zombies count as alive there).
"""
from __future__ import annotations

import os

__all__ = ["process_alive", "process_start_ticks", "stat_fields"]

_PROC = "/proc"


def stat_fields(pid: int) -> list[str] | None:
    """Fields of ``/proc/PID/stat`` after the command name, ``[state, ppid, pgrp, session, ...]``; None when the
    process does not exist (or there is no ``/proc``)."""
    try:
        with open(f"{_PROC}/{pid}/stat", "rb") as handle:
            text = handle.read().decode("ascii", errors="replace")
    except OSError:
        return None
    return text[text.rfind(")") + 2:].split()  # the command name may hold spaces and parentheses


def process_alive(pid: int) -> bool:
    """True when process ``pid`` exists on this host and has not exited (a zombie has, where ``/proc`` tells)."""
    if os.path.isdir(_PROC):
        fields = stat_fields(pid)
        return fields is not None and fields[0] not in ("Z", "X")
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, owned by another user
        return True
    except OSError:  # a pid the system refuses (negative, too large)
        return False
    return True


def process_start_ticks(pid: int) -> int | None:
    """Start time of process ``pid`` in clock ticks since boot (Linux), None if unknown or gone: with the pid it
    names one process, since a pid is reused."""
    fields = stat_fields(pid)
    try:
        return int(fields[19]) if fields is not None else None
    except (ValueError, IndexError):
        return None
