"""``dptpu bench codec``: every scanner message survives both codec paths unchanged (tiny run, no timing asserted)."""
from __future__ import annotations

import contextlib
import io
import json

from dptpu.cli.main import main

MESSAGES = {"Trigger", "ScanStatus", "FringeFrame", "CameraInfo", "PhaseMaps", "AbsolutePhase", "PointCloud2"}


def test_every_scanner_message_round_trips_equal_on_both_paths_with_the_same_header():
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main(["bench", "codec", "--json", "--size", "64x48", "--number", "3", "--repeats", "1"])
    report = json.loads(buffer.getvalue())
    assert code == 0 and report["all_equal"] is True
    assert set(report["messages"]) == MESSAGES
    for name, entry in report["messages"].items():
        assert entry["same_header"] and entry["round_trip_equal"], name
        for part in ("encode", "decode"):
            assert entry[part]["ours"]["best_us"] > 0 and entry[part]["general"]["best_us"] > 0, (name, part)
    # the arrays travel as frames of exactly their bytes: 64x48 mono8 frame, 2 x (phase + modulation) + mask
    assert report["messages"]["FringeFrame"]["array_bytes"] == 64 * 48
    assert report["messages"]["PhaseMaps"]["array_bytes"] == 2 * 2 * 64 * 48 * 4 + 64 * 48
    assert report["messages"]["PointCloud2"]["array_bytes"] == 64 * 48 * 5 * 4
