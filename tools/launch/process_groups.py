"""Process groups: who is still alive in one, and signalling all of them at once.

Every launched node leads its own session and process group (``start_new_session=True``), so one
``killpg`` reaches the node and any helper processes it started. A group is alive while it has a member
that is not a zombie: on Linux the members are found in ``/proc`` (a zombie, dead but not yet reaped by
whoever adopted it, does not count); elsewhere ``killpg(pgid, 0)`` answers, zombies included.
"""
from __future__ import annotations

import os
import signal

from dptpu.graph.processes import process_alive, stat_fields

__all__ = ["group_members", "group_alive", "signal_group", "process_alive"]

_PROC = "/proc"


def group_members(pgid: int) -> list[int]:
    """Pids of the live (non-zombie) processes in process group ``pgid`` (Linux ``/proc``; else [] or [pgid])."""
    if not os.path.isdir(_PROC):
        return [pgid] if group_alive(pgid) else []
    members = []
    for entry in os.listdir(_PROC):
        if entry.isdigit():
            fields = stat_fields(int(entry))
            if fields is not None and len(fields) > 2 and fields[2] == str(pgid) and fields[0] not in ("Z", "X"):
                members.append(int(entry))
    return members


def group_alive(pgid: int) -> bool:
    """True while process group ``pgid`` has a live member."""
    if os.path.isdir(_PROC):
        if process_alive(pgid) and (stat_fields(pgid) or ["", "", ""])[2] == str(pgid):
            return True  # the leader itself: no need to scan
        return bool(group_members(pgid))
    try:
        os.killpg(pgid, 0)
    except (ProcessLookupError, PermissionError):
        return False
    return True


def signal_group(pgid: int, signum: int) -> bool:
    """Send ``signum`` to every process of group ``pgid``; False when the group no longer exists."""
    try:
        os.killpg(pgid, signum)
    except ProcessLookupError:
        return False
    except PermissionError:  # a member changed user; nothing we may do about it
        return False
    return True


#: Signals in the order a stop escalates through them.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGKILL)
