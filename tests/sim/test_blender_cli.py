"""``dptpu sim twin`` (Table 1 printout) and ``dptpu sim setup-blender``."""
import json

import pytest

from dptpu.cli.main import main


def _run(capsys, *argv):
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_sim_twin_json_of_the_dptpu_calibration(capsys, sphere_dir):
    calibration = f"{sphere_dir / 'CamCalibResult_real.mat'},{sphere_dir / 'PrjCalibResult_real.mat'}"
    code, out, _ = _run(capsys, "sim", "twin", "--rig", calibration, "--blender", "--json")
    assert code == 0
    document = json.loads(out)
    camera, projector = document["blender"]["camera"], document["blender"]["projector"]
    assert camera["location"] == pytest.approx([109.1986, -93.2745, 835.7891], abs=1e-3)  # -R^T T, mm
    assert camera["location_m"] == pytest.approx([0.1091986, -0.0932745, 0.8357891], abs=1e-6)
    assert camera["lens_mm"] == pytest.approx(12.4423, abs=1e-4)
    assert camera["shift_x"] == pytest.approx((320 - 0.5 - 309.04737) / 640, abs=1e-6)
    assert projector["focal_length_px"] == pytest.approx([1732.1665, 3463.3285], abs=1e-3)
    assert projector["spot_size_deg"] == pytest.approx(34.41, abs=0.01)
    assert document["rig"]["baseline"] == pytest.approx(135.835, abs=1e-3)


def test_sim_twin_text_of_the_nominal_rig(capsys):
    code, out, _ = _run(capsys, "sim", "twin", "--rig", "nominal", "--blender")
    assert code == 0
    assert "angle between the optical axes 6.210 deg" in out
    assert "rotation_euler  [180.0000, 0.0000, 0.0000] deg" in out  # the camera frame is the world frame
    assert "spot_size" in out and "shift_x" in out
    code, out, _ = _run(capsys, "sim", "twin", "--rig", "nominal")
    assert code == 0 and "Blender" not in out


def test_sim_twin_bad_calibration_is_exit_code_2(capsys, tmp_path):
    code, _, err = _run(capsys, "sim", "twin", "--rig", str(tmp_path / "missing.yaml"))
    assert code == 2 and "missing.yaml" in err


def test_setup_blender_is_idempotent(capsys):
    from dptpu.sim.blender import BlenderNotInstalledError, blender_python

    try:
        blender_python()
    except BlenderNotInstalledError as exc:
        pytest.skip(f"Blender environment missing ({exc})")
    code, out, _ = _run(capsys, "sim", "setup-blender")
    assert code == 0 and "Blender environment ready" in out and "bpy 4.5" in out
