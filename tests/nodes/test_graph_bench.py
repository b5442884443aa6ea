"""``dptpu bench pipeline`` on a small image: the report's structure and its camera-limit arithmetic.

No time is asserted."""
from __future__ import annotations

import json

import pytest

from dptpu.cli.bench_cmd import PIPELINE_MODULE_NAME, load_bench
from dptpu.cli.main import main


def test_bench_pipeline_reports_one_object_per_configuration(capsys):
    code = main(["bench", "pipeline", "--json", "--size", "96x72", "--scans", "3", "--warmup", "1", "--steps", "3",
                 "--classical-only"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0
    assert report["benchmark"] == "pipeline" and report["size"] == "96x72"
    (three,) = report["configurations"]
    assert (three["frames_per_scan"], three["camera_limit_scans_per_s"]) == (6, 125.0)  # 750 frames/s / 6
    bench = load_bench("pipeline_bench.py", PIPELINE_MODULE_NAME)
    assert bench.camera_limit_scans_per_s(24) == 31.25  # the paper's camera at 2 x 12 steps
    for result in report["configurations"]:
        assert result["scans_timed"] == 3 and result["scans_failed"] == result["scans_lost"] == 0
        assert result["scans_per_s"] > 0 and 0 < result["latency_ms_p50"] <= result["latency_ms_p99"]
        # each process's CPU over the timed scans (one scan here, 2 to 3; 10 ms clock ticks, so often 0 at 96x72)
        cpu = result["cpu_ms_per_scan"]
        processes = {k: v for k, v in cpu.items() if k not in ("total", "scans", "window_s", "threads")}
        assert cpu["scans"] == 1 and {"launch", "projector", "sim", "phase", "unwrap", "cloud", "scan_monitor"} == \
            set(processes)
        assert min(processes.values()) >= 0 and cpu["total"] == pytest.approx(sum(processes.values()), abs=0.2)
        # the same processes split by thread: main, libzmq's I/O thread, the others (each rounded to clock ticks)
        assert set(cpu["threads"]) == set(processes)
        for name, threads in cpu["threads"].items():
            assert set(threads) == {"main", "zmq_io", "other"} and min(threads.values()) >= 0
            # read just after the process's own figure: at most a clock tick (10 ms) later at either end
            assert sum(threads.values()) <= processes[name] + 20.0 / cpu["scans"]
        assert result["camera_limit_ratio"] == pytest.approx(result["scans_per_s"] / result["camera_limit_scans_per_s"],
                                                             rel=1e-2)
        # the floor, measured in the same run: the work's parts, with ZeroMQ transfers or shared memory's copies
        floor = result["floor_ms_per_scan"]
        # the floor works on the graph's first scene, random-1 rendered as the sim node renders it
        assert floor["steps"] == 3 and floor["size"] == "96x72" and floor["source"] == "raycast"
        assert 0.3 * 96 * 72 < floor["valid_pixels"] <= 96 * 72
        work = sum(floor[k] for k in ("phase", "unwrap", "triangulate", "filters", "assemble"))
        assert floor["total"] == pytest.approx(work + floor["transport_in"] + floor["transport_out"], abs=0.02)
        assert floor["total_shared_memory"] == pytest.approx(work + floor["copy_in"] + floor["copy_out"], abs=0.02)
        if cpu["total"]:
            assert result["cpu_over_floor"] == pytest.approx(cpu["total"] / floor["total_shared_memory"], rel=1e-2)


def test_bench_pipeline_refuses_unknown_steps(capsys):
    assert main(["bench", "pipeline", "--steps", "5"]) == 2
    assert "--steps takes 12 and/or 3" in capsys.readouterr().err


def test_bench_pipeline_refuses_dptpu_only_beside_classical_only(capsys):
    assert main(["bench", "pipeline", "--dptpu-only", "--classical-only", "--steps", "3"]) == 2
    assert "--dptpu-only needs a DP-TPU model (--model, or the shipped one) and no --classical-only" \
        in capsys.readouterr().err


def test_bench_pipeline_floor_on_the_captures_the_graph_replays(tmp_path, capsys):
    """``--source FOLDER``: the floor works on the first capture's own frames and rig (the scene the sim replays)."""
    capture = tmp_path / "captures" / "01-random-1"
    assert main(["sim", "render", "--rig", "nominal", "--scene", "random:1", "--sequence", "64x12,1x12",
                 "--size", "96x72", "--out", str(capture)]) == 0
    capsys.readouterr()
    assert main(["bench", "pipeline", "--floor", "--json", "--size", "96x72", "--steps", "3",
                 "--source", str(capture.parent)]) == 0
    (floor,) = json.loads(capsys.readouterr().out)["floors"]
    assert floor["source"] == str(capture.parent) and floor["frames"] == 6  # 3-step: frames 0, 4, 8 of the 12
    assert 0.3 * 96 * 72 < floor["valid_pixels"] <= 96 * 72  # a scene, not the ramp the filters cut
    assert main(["bench", "pipeline", "--floor", "--size", "64x48", "--steps", "3", "--source",
                 str(capture.parent)]) == 2
    assert capsys.readouterr().err.strip().endswith(
        "holds no 64x3 and 1x3 sequences at 64x48")


def test_bench_pipeline_takes_the_analytic_ramp_for_the_floor_only(capsys):
    """``--source ramp``: the floor on an analytic steep plane (no graph replays it: refused without ``--floor``)."""
    assert main(["bench", "pipeline", "--steps", "3", "--source", "ramp"]) == 2
    assert "--source ramp (the analytic ramp) is for --floor only" in capsys.readouterr().err
    assert main(["bench", "pipeline", "--floor", "--json", "--size", "64x48", "--steps", "3", "--source", "ramp"]) == 0
    (floor,) = json.loads(capsys.readouterr().out)["floors"]
    assert floor["source"] == "ramp" and floor["frames"] == 6 and 0 < floor["valid_pixels"] <= 64 * 48
