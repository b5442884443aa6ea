"""The main job end to end: ``dptpu launch launch/sim_rig.yaml`` runs the whole graph as separate processes.

projector (emulated trigger box) -> sim (twin frames) -> phase -> unwrap -> cloud -> scan monitor, at 160x120.
The monitor grades every scan against the twin's ground truth (``dptpu.nodes.scan_monitor.scan_metrics``) and ends
the launch after ``scans:=N`` with exit code 0. Bounds (docs/scanner.md): with 16x12,1x12 and classical MF
(``model:=none``: these tests pin the classical order; the main job's default is DP-TPU) every scan has at least
99.5 % of its fringe orders right and a depth RMS below 1.5 mm (measured: 100 % and 0.42-0.84 mm; at f = 16
a phase noise of 0.02 rad is 0.18 projector pixels, about 0.45 mm of depth at 800 mm), and the monitor calls it
``ok``: at most 0.1 % of its points wrong and at least 50 % complete (measured with the confidence and depth-edge
filters: 0.000 % wrong, 93.0-94.1 % complete on the objects, 64.7 % on the board, whose black squares fall under
the phase node's min_modulation).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

from tests.launch_files.running import REPO_ROOT, SIM_RIG, TWIN_RIG_ARG, LaunchRun

ORDER_ACCURACY_BOUND = 0.995
DEPTH_RMS_BOUND_MM = 1.5
# the live raycast twin on the round-number rig, not the shipped renders
SMALL = ("source:=raycast", TWIN_RIG_ARG, "size:=160x120", "sequence:=16x12,1x12", "method:=mf", "model:=none")


def _check_scan(record: dict) -> None:
    assert record["outcome"] == "ok", record
    assert record["order_accuracy"] >= ORDER_ACCURACY_BOUND, record
    assert record["depth_rms_mm"] < DEPTH_RMS_BOUND_MM, record
    assert record["valid_points"] > 0.5 * record["depth_pixels"] > 0, record
    assert record["wrong_share"] <= 0.001 and record["completeness"] >= 0.5, record


def test_n_scans_through_the_whole_graph_meet_the_documented_bounds_and_a_dropped_frame_fails_one(node_env, tmp_path):
    summary = tmp_path / "summary.json"
    env = dict(os.environ, **node_env, PYTHONPATH=str(REPO_ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    # the robot and `dptpu topic echo` start first, so they listen before the first cloud
    echo = subprocess.Popen([sys.executable, "-c", "import sys; from dptpu.cli.main import main; sys.exit(main())",
                             "topic", "echo", "/scanner/points", "--once", "--timeout", "120", "--spin-time", "60"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    robot = subprocess.Popen([sys.executable, str(REPO_ROOT / "examples" / "subscriber.py")], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    run = LaunchRun(SIM_RIG, "scans:=6", *SMALL, "drop_frames:=5/5", f"summary:={summary}",
                    f"ply_dir:={tmp_path / 'ply'}", "ply_count:=2", env=node_env, cwd=tmp_path)
    try:
        assert run.wait(timeout=150) == 0, run.text()
        echoed, echo_err = echo.communicate(timeout=60)
    finally:
        echo.kill()
        robot.kill()
        run.close()
    robot_lines = robot.communicate(timeout=10)[0].splitlines()
    assert robot_lines and all(line.startswith("160x120 cloud, ") for line in robot_lines), robot_lines
    assert echo.returncode == 0, echo_err[-2000:]
    assert "height: 120" in echoed and "width: 160" in echoed and "frame_id: scanner_optical_frame" in echoed
    report = json.loads(summary.read_text())
    assert report["totals"]["scans"] == 6 and report["totals"]["ok"] == 5, run.text()
    records = {r["sequence_id"]: r for r in report["scans"]}
    assert [records[i]["scene"] for i in range(1, 5)] == ["random-1", "sphere", "random-2", "board-11x8"]
    for sequence_id in (1, 2, 3, 4, 6):  # scan 6 comes right after the incomplete one
        _check_scan(records[sequence_id])
        # the monitor's first pattern of each scan, from the projector's TriggerBursts (the sim rig's default): 24
        # patterns of 1.333 ms before the last frame's stamp, which the cloud's latency counts from
        record = records[sequence_id]
        assert record["latency_from_first_trigger_ms"] > record["latency_ms"] > 0, record
    assert records[5]["outcome"] == "failed", records[5]
    assert "/phase: incomplete after 2 s: received 23 of 24 frames; missing pattern 5 (f=16 step 5)" \
        in records[5]["reason"]
    assert "dropping pattern 5 of scan 5 (drop_frames)" in run.text(300)
    assert sorted(p.name for p in (tmp_path / "ply").iterdir()) == ["scan_00000001.ply", "scan_00000002.ply"]
    assert "all processes stopped" in run.text()


def test_dptpu_scans_through_the_whole_graph_meet_the_bounds(node_env, tmp_path):
    """DP-TPU (the shipped model refining MF's fringe order, Fig. 8b) on the paper's S4 frequency 64 with f_l = 1.

    Bound: at least 95 % of fringe orders right per scan, depth RMS where the order is right below 1 mm. Measured
    (2026-11-23, 160x120, twin_rig): the shipped architecture-2 model trained on the nominal + wide rigs
    (models/README.md) 97.67 / 99.01 / 97.17 / 99.66 % on random-1 / sphere / random-2 / board; the one trained
    on the nominal rig alone 97.57 / 98.33 / 97.29 / 95.26 %, depth RMS 0.10-0.21 mm; the previous (architecture 1)
    model 99.49 / 97.95 / 99.38 / 97.25 %; classical MF 99.68 / 98.93 / 99.17 / 100 % in the same graph. On these
    160x120 12-step frames (finer fringes per pixel than its 320x240 3-step training data) the shipped model does
    not beat classical MF; the bound guards the wiring and against a broken model (an untrained one would return
    the classical order), not the paper's claim, which issue [4/7] still owes. The monitor's verdict must
    agree with its own figures: ``ok`` within its bounds, else UNTRUSTED naming the share it computed from the scan's
    wrong orders and off-surface points (measured 2026-11-26 with the confidence and depth-edge filters: 0.000-0.092 %
    wrong, all ok; before the filters 0.29-2.79 %, all UNTRUSTED).
    """
    import pytest

    from dptpu.models.inference import shipped_model_path

    if shipped_model_path() is None:
        pytest.skip("no shipped DP-TPU model (models/dptpu.onnx) yet")
    summary = tmp_path / "summary.json"
    run = LaunchRun(SIM_RIG, "scans:=4", "source:=raycast", TWIN_RIG_ARG, "size:=160x120", "sequence:=64x12,1x12",
                    "method:=mf", "model:=shipped", f"summary:={summary}", "ply_dir:=", env=node_env, cwd=tmp_path)
    try:
        assert run.wait(timeout=200) == 0, run.text()
    finally:
        run.close()
    records = json.loads(summary.read_text())["scans"]
    assert len(records) == 4
    for record in records:
        assert record["outcome"] in ("ok", "untrusted") and record["method"] == "dptpu", record
        assert record["order_accuracy"] >= 0.95 and record["depth_rms_right_order_mm"] < 1.0, record
        assert record["wrong_points"] == record["wrong_order_points"] + record["off_surface_points"], record
        assert record["wrong_share"] == record["wrong_points"] / record["valid_points"], record
        assert record["wrong_order_points"] <= record["order_errors"], record  # published pixels only
        trusted = record["wrong_share"] <= 0.001 and record["completeness"] >= 0.5
        assert (record["outcome"] == "ok") == trusted, record
        if not trusted:
            assert f"{100 * record['wrong_share']:.2f} % of the points wrong (> 0.10 %)" in record["reason"], record
