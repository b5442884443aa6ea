"""Writing an announcement leaves no reference cycles behind (issue 19's soak).

A node rewrites its announcement about once a second. ``json.dump`` always runs the pure-Python encoder, whose nested
functions form reference cycles on every call; the nodes collect the young generation only every 5,000 net
allocations (``dptpu.nodes.node_main.freeze_startup_objects``), so the cycles of thousands of writes stayed in
memory: the scan monitor and the projector grew all through a 5,000-scan soak.
"""
from __future__ import annotations

import gc
import json

from dptpu.graph.discovery import write_announcement


def test_announcement_writes_leave_no_garbage_cycles_and_the_file_is_the_entry(tmp_path):
    entry = {"format": "dptpu-graph/1", "fqn": "/projector", "publishers": [{"topic": "/t", "stats": {"sent": 3}}],
             "start_time": 1.5, "curve_public_key": None}
    gc.collect()
    gc.disable()  # no automatic collection in between: each write's cycles stay to be counted
    try:
        for count in range(200):
            entry["publishers"][0]["stats"]["sent"] = count
            write_announcement(tmp_path, "n-1-abc.json", entry)
    finally:
        gc.enable()
    assert gc.collect() == 0  # json.dump: thousands of unreachable objects (about 30 a write)
    assert json.loads((tmp_path / "n-1-abc.json").read_text()) == entry
    assert list(tmp_path.iterdir()) == [tmp_path / "n-1-abc.json"]  # no temporary file left
