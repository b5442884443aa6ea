"""``dptpu eval unwrap``: a tiny run end to end, reuse of its test set, and option errors (exit code 2)."""
from __future__ import annotations

import csv

import cv2

from dptpu.cli.main import main


def _table(path):
    with path.open() as handle:
        return list(csv.DictReader(handle))


def test_eval_unwrap_tiny_run_then_reuse_with_another_model_choice(tmp_path, capsys):
    out = tmp_path / "eval"
    assert main(["eval", "unwrap", "--model", "none", "--frequencies", "16,96", "--noise", "1.5693",
                 "--scenes", "1", "--size", "160x120", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "No model was evaluated" in printed and "heatmap.png" in printed
    rows = _table(out / "table.csv")
    assert len(rows) == 2 * 3 * 2  # frequencies x methods x (classical, classical+median)
    assert {r["solver"] for r in rows} == {"classical", "classical+median"}
    low = [float(r["accuracy"]) for r in rows if r["frequency"] == "16" and r["solver"] == "classical"]
    assert min(low) > 0.97  # measured 98.2-99.3 % on this scene (tests/models/test_unwrap_eval.py)
    assert cv2.imread(str(out / "heatmap.png")) is not None
    assert cv2.imread(str(out / "error_vs_frequency.png")) is not None
    # the same test set again, from --data: same classical numbers, nothing rendered
    again = tmp_path / "again"
    assert main(["eval", "unwrap", "--model", "none", "--data", str(out / "testset"), "--out", str(again)]) == 0
    assert _table(again / "table.csv") == rows
    assert "seed root 300 at 160x120" in (again / "summary.md").read_text()
    # --vote-baseline: the consensus vote on the prior alone, as a third solver (NT: its band prior's order)
    voted = tmp_path / "voted"
    assert main(["eval", "unwrap", "--model", "none", "--vote-baseline", "--data", str(out / "testset"),
                 "--quiet", "--out", str(voted)]) == 0
    vote_rows = [r for r in _table(voted / "table.csv") if r["solver"] == "classical+vote"]
    assert len(vote_rows) == 2 * 3
    nt_96 = {r["solver"]: float(r["accuracy"]) for r in _table(voted / "table.csv")
             if r["method"] == "nt" and r["frequency"] == "96"}
    assert nt_96["classical+vote"] > nt_96["classical"] + 0.2  # measured 49.4 -> 80.0 % (2-px fringes at 160x120)
    assert "`classical+vote`" in (voted / "summary.md").read_text()


def test_eval_unwrap_bad_options_exit_2(tmp_path, capsys):
    assert main(["eval", "unwrap", "--frequencies", "16,abc", "--model", "none", "--out", str(tmp_path)]) == 2
    assert "--frequencies must be comma-separated numbers" in capsys.readouterr().err
    assert main(["eval", "unwrap", "--model", str(tmp_path / "missing.onnx"), "--out", str(tmp_path)]) == 2
    assert "missing.onnx: model file not found" in capsys.readouterr().err
    assert main(["eval", "unwrap", "--model", "none", "--size", "160by120", "--out", str(tmp_path)]) == 2
    assert "size must be WIDTHxHEIGHT" in capsys.readouterr().err
