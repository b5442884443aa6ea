"""The fault matrix of the running sim rig: a node killed (``kill -9``) or paused (``SIGSTOP`` for some seconds, then
``SIGCONT``), and the time until the scanner delivers five correct scans in a row again.

Shared by the CI test (``tests/nodes/test_graph_reliability.py``: a few faults, short pauses) and the full run
(``python -m tests.nodes.fault_matrix``: every node, kill -9 and pauses of 1, 5 and 30 s, results in
docs/reliability.md). One launch serves every fault in turn: each fault starts once the previous one's recovery
was seen, so a fault's scans in flight are the only ones it may cost.

A scan is *correct* when the monitor reports it ``ok`` (inside the precision and completeness bounds against the
twin's ground truth) with a fringe-order accuracy of at least ``ORDER_ACCURACY_BOUND``.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from tests.launch_files.running import SIM_RIG, LaunchRun

ORDER_ACCURACY_BOUND = 0.995
#: The whole-graph tests' small rig (tests/nodes/test_graph_sim_rig.SMALL, repeated so that the script needs no test
#: module): raycast frames at 160x120, the round-number twin rig, MF with its classical order.
_REPO_ROOT = Path(__file__).resolve().parents[2]
SMALL = ("source:=raycast", f"rig:={_REPO_ROOT / 'launch' / 'params' / 'twin_rig.yaml'}", "size:=160x120",
         "sequence:=16x12,1x12", "method:=mf", "model:=none")
IN_A_ROW = 5
#: Nodes whose processes a fault hits; the scan monitor is the launch's required node (its exit ends the launch),
#: so it is only paused, never killed.
NODES = ("projector", "sim", "phase", "unwrap", "cloud", "scan_monitor")


@dataclass
class Recovery:
    """One fault and what it cost."""

    node: str
    fault: str              # "kill -9" or "SIGSTOP 5 s"
    last_before: int        # sequence id of the last scan reported before the fault
    recovered_s: float      # from the fault's start to the fifth correct scan in a row
    after_resume_s: float   # from SIGCONT (or the kill) to the same scan
    not_ok: int             # scans reported other than correct between the fault and the recovery
    respawned: bool         # the launcher started a new process of the node


def correct(line: str, outcome: str) -> bool:
    """A monitor line of a correct scan (``ok``, fringe orders >= ``ORDER_ACCURACY_BOUND``)."""
    if outcome != "ok" or "fringe orders " not in line:
        return False
    return float(line.split("fringe orders ")[1].split(" %")[0]) / 100.0 >= ORDER_ACCURACY_BOUND


def _run_of_correct(run: LaunchRun, reported_before: int, streak_from: int | None = None) -> tuple[bool, int]:
    """``(five correct in a row seen, scans reported not correct)`` among the scans reported after the first
    ``reported_before`` (by position: a new projector numbers its scans from 1 again); the five count only from
    position ``streak_from`` on (default: ``reported_before``)."""
    streak = 0
    bad = 0
    for position, (_sequence_id, _scene, outcome, line) in enumerate(run.scans()[reported_before:], reported_before):
        if correct(line, outcome):
            if streak_from is not None and position < streak_from:
                continue
            streak += 1
            if streak >= IN_A_ROW:
                return True, bad
        else:
            streak = 0
            bad += 1
    return False, bad


def inject(run: LaunchRun, node: str, fault: str, seconds: float, *, timeout: float) -> Recovery:
    """Apply ``fault`` ("kill" or "stop" for ``seconds``) to ``node`` and wait for five correct scans in a row."""
    pid = run.pids(node)[-1]
    processes_before = len(run.pids(node))
    scans = run.scans()
    last_before = max((s[0] for s in scans), default=0)
    reported_before = len(scans)
    start = time.monotonic()
    if fault == "kill":
        os.killpg(pid, signal.SIGKILL)
        label = "kill -9"
    else:
        os.killpg(pid, signal.SIGSTOP)
        time.sleep(seconds)
        os.killpg(pid, signal.SIGCONT)
        label = f"SIGSTOP {seconds:g} s"
    resumed = time.monotonic()
    # the lines of scans finished before the fault may reach the launcher's output late: the five in a row count
    # from the scans reported a second after the fault's end
    time.sleep(1.0)
    streak_from = len(run.scans())
    run.wait_for(lambda lines: _run_of_correct(run, reported_before, streak_from)[0], timeout,
                 f"{IN_A_ROW} correct scans in a row after {label} of {node}")
    done = time.monotonic()
    return Recovery(node, label, last_before, done - start, done - resumed, _run_of_correct(run, reported_before)[1],
                    len(run.pids(node)) > processes_before)


def start_rig(env: dict, cwd, *extra: str) -> LaunchRun:
    """The sim rig scanning until interrupted, at the small size, one scan in flight."""
    return LaunchRun(SIM_RIG, "scans:=0", *SMALL, "ply_dir:=", "scan_timeout:=3.0", *extra, env=env, cwd=cwd)


def markdown(rows: list[Recovery]) -> str:
    """The matrix as a markdown table: one row per node, one column per fault (seconds to recovery)."""
    faults = list(dict.fromkeys(r.fault for r in rows))
    lines = ["| node | " + " | ".join(faults) + " |", "|---|" + "---|" * len(faults)]
    for node in dict.fromkeys(r.node for r in rows):
        cells = []
        for fault in faults:
            hit = [r for r in rows if r.node == node and r.fault == fault]
            cells.append(f"{hit[0].recovered_s:.1f} s ({hit[0].not_ok} lost)" if hit else "n/a")
        lines.append(f"| {node} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m tests.nodes.fault_matrix [OUT.json] [PAUSES]``: every node, kill -9 and SIGSTOP for each pause
    (default 1,5,30 s), one launch; prints the markdown table and writes the rows as JSON."""
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]) if argv else Path("fault_matrix.json")
    pauses = [float(p) for p in argv[1].split(",")] if len(argv) > 1 else [1.0, 5.0, 30.0]
    folder = Path(tempfile.mkdtemp(prefix="dptpu-faults-"))
    env = {"DPTPU_DISCOVERY_DIR": str(folder / "discovery"), "DPTPU_DOMAIN_ID": "42"}
    run = start_rig(env, folder)
    rows: list[Recovery] = []
    try:
        run.wait_for(lambda lines: _run_of_correct(run, 0)[0], 300, "the first five correct scans")
        for node in NODES:
            faults = [("stop", p) for p in pauses] + ([("kill", 0.0)] if node != "scan_monitor" else [])
            for fault, seconds in faults:
                row = inject(run, node, fault, seconds, timeout=300)
                rows.append(row)
                print(json.dumps(asdict(row)), flush=True)
                out.write_text(json.dumps([asdict(r) for r in rows], indent=1))
    finally:
        run.close()
    print(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
