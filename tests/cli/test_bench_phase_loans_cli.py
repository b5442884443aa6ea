"""``dptpu bench phase_loans``: both variants run and report (tiny size); no time is asserted."""
from __future__ import annotations

import json

from dptpu.cli import bench_cmd
from dptpu.graph.publisher import Publisher


def test_both_variants_report_their_runs_and_the_loan_check_is_restored(capsys, monkeypatch):
    monkeypatch.setenv("DPTPU_SHM_MIN_BYTES", "1024")  # the 64x48 maps (25 kB) through shared memory
    original = Publisher.can_loan_messages
    module = bench_cmd.load_target("phase_loans")
    assert module.main(["--size", "64x48", "--steps", "4", "--scans", "1", "--pairs", "1", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    runs = report["runs"]["2x4"]
    assert set(runs) == {"loaned", "copied"}
    for variant in runs.values():  # each run went through shared memory (checked by the bench) and was timed
        assert len(variant["ms"]) == 1 and variant["median_ms"] == variant["ms"][0] > 0
    assert Publisher.can_loan_messages is original  # the A/B's patch is undone
