"""The sim's ``shipped`` source replays the shipped renders only for the rig they were made with (issue 16/18):
``dptpu launch sim_rig.yaml rig:=MY_RIG.yaml`` at the shipped size and sequences replayed the 912x1140 renders
while the projector and the cloud node took MY_RIG's geometry, and the monitor called a scan with a depth RMS of
368 mm "ok". Another rig now gets live raycast renders of itself, and the note says why."""
from __future__ import annotations

import pytest

from dptpu.fpp.calibration import save_rig
from dptpu.nodes.sim import source as sim_source
from dptpu.sim.outside_rigs import PROJECTOR_PANELS, outside_rig
from tests.launch_files.running import REPO_ROOT

SHIPPED_RIG = REPO_ROOT / "launch" / "params" / "shipped_rig.yaml"


@pytest.fixture(scope="module")
def shipped():
    if not sim_source._capture_folders(sim_source.shipped_root()):
        pytest.skip("no shipped renders in sim/shipped")
    return sim_source.capture_scenes(sim_source.shipped_root())


def test_the_shipped_renders_serve_their_own_rig_only(shipped, tmp_path):
    found, renders_rig, _, _ = shipped
    width, height = renders_rig.camera.size
    size = f"{width}x{height}"
    held = ",".join(f"{f:g}x{n}" for f, n in list(found[0].frames)[:2])
    assert sim_source._shipped_lacks(found, renders_rig, size, held, str(SHIPPED_RIG)) == ""
    xga = outside_rig(camera_focal_px=1800.0, baseline_mm=150.0, angle_deg=14.0, panel=PROJECTOR_PANELS[1])
    other = save_rig(xga, tmp_path / "xga.yaml")
    assert sim_source._shipped_lacks(found, renders_rig, size, held, str(other)) == (
        f"the rig {other} (they were made with another rig; projector 912x1140, the asked rig's 1024x768)")
