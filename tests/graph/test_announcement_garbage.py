"""Writing an announcement leaves no reference cycles behind, and a graph snapshot leaves no tuples in CPython's free
lists (issue 19's soak).

A node rewrites its announcement about once a second. ``json.dump`` always runs the pure-Python encoder, whose nested
functions form reference cycles on every call; the nodes collect the young generation only every 5,000 net
allocations (``dptpu.nodes.node_main.freeze_startup_objects``), so the cycles of thousands of writes stayed in
memory: the scan monitor and the projector grew all through a 5,000-scan soak.
"""
from __future__ import annotations

import gc
import json
import sys

from dptpu.graph.discovery import snapshot_from_entries, write_announcement


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


def test_graph_snapshots_leave_the_allocated_blocks_flat():
    """A node takes a snapshot of the graph about once a second (the scan monitor twice). Tuples built from
    generators are never taken from CPython's tuple free lists but given back to them, so each snapshot added to
    those lists until each held 2,000 tuples of its size: +10,155 blocks here before, +349 now (the dict, list and
    set free lists, 80 each at most)."""
    entries = [{"format": "dptpu-graph/1", "name": name, "namespace": "/", "fqn": f"/{name}", "gid": f"{index:032x}",
                "pid": 100 + index, "start_time": 1.0,
                "publishers": [{"topic": f"/{name}/out{k}", "type": "dptpu/msg/Image", "gid": f"{index}{k}",
                                "endpoints": [f"ipc:///tmp/x{index}{k}"]} for k in range(index + 1)],
                "subscriptions": [{"topic": "/in", "type": "dptpu/msg/Image", "gid": f"s{index}", "endpoints": []}],
                "services": [{"name": f"/{name}/get_parameters", "type": "rcl_interfaces/srv/GetParameters"}] * 3,
                "clients": []} for index, name in enumerate(("projector", "sim", "phase", "unwrap", "cloud"))]
    for _ in range(10):
        snapshot_from_entries(entries)  # the sizes' first tuples
    gc.collect()
    gc.disable()
    try:
        before = sys.getallocatedblocks()
        for _ in range(3000):
            snapshot = snapshot_from_entries(entries)
        del snapshot
        grown = sys.getallocatedblocks() - before
    finally:
        gc.enable()
    assert grown < 1000, grown
