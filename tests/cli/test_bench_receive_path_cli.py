"""``dptpu bench receive_path``: a publisher process's bursts reach the node through shared memory, every frame is
timed and none is lost (320x240: 76.8 kB a frame, above the shared-memory threshold); no time is asserted."""
from __future__ import annotations

import json

from dptpu.cli import bench_cmd


def test_two_bursts_arrive_whole_through_shared_memory_and_are_timed(capsys):
    module = bench_cmd.load_target("receive_path")
    assert module.main(["--size", "320x240", "--bursts", "2", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["frames"] == 2 * module.FRAMES_PER_BURST  # the timed bursts, after the warm-up ones
    assert report["lost"] == 0 and report["dropped"] == 0
    assert report["shared_memory"] is True
    assert report["main_us_per_frame"] > 0 and report["process_us_per_frame"] >= report["main_us_per_frame"]


def test_a_bad_size_is_refused_with_exit_code_2(capsys):
    module = bench_cmd.load_target("receive_path")
    assert module.main(["--size", "640by480"]) == 2
    assert "--size must be WIDTHxHEIGHT" in capsys.readouterr().err
