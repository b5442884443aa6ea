"""``dptpu launch sim_rig.yaml rig:=MY_RIG.yaml`` with a projector other than the DLP4500 (issue 16/18, outside
tester): the projector node takes its panel size from the rig, so the whole graph scans a rig of an XGA DMD
(1024x768). Before, launch/params/projector_sim.yaml fixed the panel at 912x1140 and every scan FAILED: "the
scan's projector is 912x1140; the rig's is 1024x768". Bounds as tests/nodes/test_graph_sim_rig.py's (docs/scanner.md).
"""
from __future__ import annotations

import json

from dptpu.fpp.calibration import save_rig
from dptpu.sim.outside_rigs import PROJECTOR_PANELS, outside_rig
from tests.launch_files.running import SIM_RIG, LaunchRun


def test_the_sim_rig_scans_a_rig_whose_projector_is_not_the_dlp4500(node_env, tmp_path):
    # the outside tester's geometry (focal 1800 px, projector 150 mm to the side turned in by 14 deg), an XGA DMD
    rig = outside_rig(camera_focal_px=1800.0, baseline_mm=150.0, angle_deg=14.0, panel=PROJECTOR_PANELS[1])
    assert rig.projector.size == (1024, 768)
    rig_path = save_rig(rig, tmp_path / "xga_rig.yaml")
    summary = tmp_path / "summary.json"
    run = LaunchRun(SIM_RIG, "scans:=2", f"rig:={rig_path}", "size:=160x120", "scenes:=sphere",
                    "sequence:=16x12,1x12", "method:=mf", "model:=none", "ply_dir:=", f"summary:={summary}",
                    env=node_env, cwd=tmp_path)
    try:
        assert run.wait(timeout=150) == 0, run.text()
    finally:
        run.close()
    assert any("24 patterns loaded" in line for line in run.lines), run.text()
    report = json.loads(summary.read_text())
    assert report["totals"]["scans"] == 2 and report["totals"]["ok"] == 2, run.text()
    for record in report["scans"]:
        assert record["order_accuracy"] >= 0.995 and record["depth_rms_mm"] < 1.5, record
        assert record["wrong_share"] <= 0.001 and record["completeness"] >= 0.5, record
