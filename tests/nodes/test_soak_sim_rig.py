"""Soak: many scans through the whole sim rig as fast as it goes, and no node's resident memory grows.

The test runs ``DPTPU_SOAK_SCANS`` scans (default the full 1,000: about 80 s on the shared 2-core build machine,
under the brief's 3 minutes; set e.g. ``DPTPU_SOAK_SCANS=200`` for a quicker run; figures in docs/scanner.md) at
160x120 with two scans in flight. Every node's ``VmRSS`` is sampled twice a second; the bound is the brief's: after
the warm-up (the first fifth of the scans) no process grows by more than 10 % (median of the first tenth of the
samples after the warm-up against the median of the last tenth, at least three each: the scan monitor gives freed
memory back, so its resident size follows the messages it holds at the moment, +-1 MB); ``DPTPU_SOAK_GROWTH`` sets
another. Sampling ends with the last scan's report: the nodes' shutdown (the launcher's SIGINT) allocates too, and
samples of it once made the projector look 600 KB larger at the end. Issue 19's soak, 5,000 scans within 1 %, is
``DPTPU_SOAK_SCANS=5000 DPTPU_SOAK_GROWTH=0.01`` (``-s`` prints the per-process figures; docs/reliability.md).
"""
from __future__ import annotations

import json
import os
import threading
import time

import numpy as np

from tests.launch_files.running import SIM_RIG, LaunchRun, rss_kib
from tests.nodes.test_graph_sim_rig import SMALL

SCANS = int(os.environ.get("DPTPU_SOAK_SCANS", "1000"))
GROWTH_BOUND = float(os.environ.get("DPTPU_SOAK_GROWTH", "0.10"))
NODES = ("projector", "sim", "phase", "unwrap", "cloud", "scan_monitor")


def test_soak_no_resident_memory_growth_after_warm_up(node_env, tmp_path):
    summary = tmp_path / "summary.json"
    run = LaunchRun(SIM_RIG, f"scans:={SCANS}", *SMALL, "in_flight:=2", "ply_dir:=", f"summary:={summary}",
                    env=node_env, cwd=tmp_path)
    samples: list[tuple[int, dict]] = []  # (scans reported, {node: rss KiB})
    stop = threading.Event()

    def sample() -> None:
        while not stop.wait(0.5):
            pids = {name: run.pids(name) for name in NODES}
            reported = len(run.scans())
            if reported >= SCANS:  # the last scan is in: what follows is the graph stopping, not scanning
                return
            if all(len(p) == 1 for p in pids.values()):
                rss = {name: rss_kib(p[0]) for name, p in pids.items()}
                if all(rss.values()) and len(run.scans()) < SCANS:
                    samples.append((reported, rss))

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    started = time.monotonic()
    try:
        assert run.wait(timeout=60 + 1.5 * SCANS) == 0, run.text()
    finally:
        stop.set()
        sampler.join(timeout=5)
        run.close()
    elapsed = time.monotonic() - started
    totals = json.loads(summary.read_text())["totals"]
    warm = [rss for count, rss in samples if count >= SCANS // 5]
    assert len(warm) >= 4, f"only {len(warm)} samples after warm-up"
    # medians of a tenth of the samples (at least three), so what a node holds at one moment does not decide
    tenth = max(3, len(warm) // 10)
    baseline = {name: int(np.median([rss[name] for rss in warm[:tenth]])) for name in NODES}
    final = {name: int(np.median([rss[name] for rss in warm[-tenth:]])) for name in NODES}
    growth = {name: (final[name] - baseline[name]) / baseline[name] for name in NODES}
    fifths = [warm[round(i * (len(warm) - 1) / 4)] for i in range(5)]  # the curve: a leak grows, a heap settles
    print("\nRSS (KiB) over the run after the warm-up, in fifths:\n" + "\n".join(
        f"  {name}: {[rss[name] for rss in fifths]}" for name in NODES))
    print(f"\nsoak: {SCANS} scans in {elapsed:.0f} s; {totals}\nRSS after warm-up (KiB): {baseline}\n"
          f"RSS at the end (KiB): {final}\ngrowth: { {k: round(100 * v, 1) for k, v in growth.items()} } %")
    assert totals["scans"] == SCANS and totals["ok"] >= SCANS - 2, totals  # nothing lost when nothing goes wrong
    assert totals["order_accuracy"] >= 0.995
    assert max(growth.values()) <= GROWTH_BOUND, growth
