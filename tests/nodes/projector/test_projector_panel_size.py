"""The projector's panel size follows the rig (issue 16/18, outside tester): ``dptpu launch sim_rig.yaml
rig:=MY_RIG.yaml`` with a projector other than the DLP4500 failed every scan ("the scan's projector is 912x1140;
the rig's is 1024x768"), because the sim projector's size was fixed in launch/params/projector_sim.yaml."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from dptpu.fpp.calibration import save_rig
from dptpu.nodes.projector.node import DLP4500_SIZE, panel_size
from dptpu.sim.outside_rigs import PROJECTOR_PANELS, outside_rig


@pytest.fixture(scope="module")
def xga_rig(tmp_path_factory):
    """A rig file whose projector is an XGA DMD, 1024x768."""
    rig = outside_rig(camera_focal_px=1400.0, baseline_mm=120.0, angle_deg=10.0, panel=PROJECTOR_PANELS[1])
    return save_rig(rig, tmp_path_factory.mktemp("rig") / "xga_rig.yaml")


def test_the_panel_size_is_the_rigs_projectors_unless_given(xga_rig):
    assert panel_size([0, 0], str(xga_rig)) == (1024, 768)
    assert panel_size([1024, 768], str(xga_rig)) == (1024, 768)  # given and the rig's: the same
    assert panel_size([0, 0], "") == DLP4500_SIZE == (912, 1140)  # no rig: the LightCrafter 4500
    assert panel_size([1280, 800], "") == (1280, 800)


def test_a_size_other_than_the_rigs_is_refused_naming_both(xga_rig):
    with pytest.raises(ValueError, match=rf"parameter projector_size is 912x1140 but the projector of rig "
                                         rf"{xga_rig} is 1024x768: leave projector_size out"):
        panel_size([912, 1140], str(xga_rig))


def test_the_node_refuses_to_start_with_one_line_and_exit_code_2(xga_rig, node_env):
    # the hardware launch files give both (params/dlp4500.yaml's size and the launch's rig): a calibration of
    # another projector is refused at start, not scan by scan
    result = subprocess.run([sys.executable, "-m", "dptpu.nodes.projector", "--ros-args", "-p", "port:=loop://",
                             "-p", f"rig:={xga_rig}", "-p", "projector_size:=[912, 1140]"],
                            capture_output=True, text=True, timeout=120, env={**os.environ, **node_env})
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "912x1140" in lines[0] and "1024x768" in lines[0], result.stderr
    assert "Traceback" not in result.stderr
