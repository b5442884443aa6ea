"""``dptpu bench camera_bursts``: both variants run the camera node on viky and report (tiny windows); no time is
asserted."""
from __future__ import annotations

import json
import os

from dptpu.cli import bench_cmd


def test_both_variants_answer_every_trigger_and_report_their_rounds(capsys):
    before = {name: os.environ.get(name) for name in ("DPTPU_DISCOVERY_DIR", "DPTPU_DOMAIN_ID")}
    module = bench_cmd.load_target("camera_bursts")
    assert module.main(["--size", "160x120", "--rate", "100", "--steps", "3", "--seconds", "0.4", "--rounds", "1",
                        "--pairs", "1", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report["runs"]) == {"frames", "bursts"}
    for (run,) in report["runs"].values():  # the bench raises when fewer than 90 % of the Triggers got a frame
        assert run["triggers"] >= 6 and run["idle_cpu_s_per_s"] > 0  # viky's frames are fetched while idle
        assert run["rounds_us_per_frame"] == [run["us_per_frame"]]
        assert run["handling_us_per_frame"] > 0  # the child node timed the frames it handled and said so at exit
    assert {name: os.environ.get(name) for name in before} == before  # the private graph's variables undone


def test_bad_options_exit_2_with_one_line(capsys):
    module = bench_cmd.load_target("camera_bursts")
    assert module.main(["--rate", "500"]) == 2
    assert capsys.readouterr().err.strip().startswith("dptpu bench camera_bursts: --rate must be 1..200")
