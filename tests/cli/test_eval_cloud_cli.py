"""``dptpu eval cloud``: a tiny run end to end (classical only) and option errors (exit code 2)."""
from __future__ import annotations

import json

from dptpu.cli.main import main


def test_eval_cloud_tiny_run_prints_and_writes_the_table(tmp_path, capsys):
    out = tmp_path / "cloud"
    assert main(["eval", "cloud", "--model", "none", "--steps", "12", "--noise", "0,1", "--methods", "mw",
                 "--supersample", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| 12 | 0 sigma | mw | 0.000 |" in printed  # no mixed pixels, no noise: no wrong point
    assert "| 12 | 1 sigma | mw |" in printed and "cloud_eval.json" in printed
    saved = json.loads((out / "cloud_eval.json").read_text())
    assert [p["noise_sigma"] for p in saved["pooled"]] == [0.0, 1.0] and saved["cfpe"] == []


def test_eval_cloud_refuses_unknown_rigs_and_methods_with_exit_code_2(tmp_path, capsys):
    assert main(["eval", "cloud", "--rigs", "nope", "--out", str(tmp_path)]) == 2
    assert "--rigs: unknown rig(s) nope; known: f1800-b150-14deg" in capsys.readouterr().err
    assert main(["eval", "cloud", "--methods", "heterodyne", "--out", str(tmp_path)]) == 2
    assert "methods must be among mf, mw, nt" in capsys.readouterr().err
