import json

import numpy as np

from dptpu.cli.main import main
from dptpu.fpp.calibration import load_rig


def test_eval_sphere_json(sphere_dir, capsys):
    assert main(["eval", "sphere", "--data", str(sphere_dir), "--json"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert "reconstructing the sphere: 100%" in captured.err and "4/4" in captured.err  # the bar, on stderr
    keys = {"calib_real_phase_real", "calib_twin_phase_real", "calib_real_phase_twin", "calib_twin_phase_twin"}
    assert set(report["paper"]) == keys and set(report["ours"]) == keys
    # The four Fig. 3 figures, as a set (two labels are swapped in the paper; test_real_sphere pins which).
    figures = sorted(report["paper_figures_um"].values())
    assert np.max(np.abs(np.array(sorted(report["paper"].values())) - figures)) < 0.01
    assert {"rms_um", "radius_mm", "points"} <= set(report["ours"]["calib_twin_phase_twin"])
    assert abs(report["paper"]["calib_twin_phase_twin"] - 28.256) < 0.01


def test_eval_sphere_missing_folder_is_exit_2(tmp_path, capsys):
    assert main(["eval", "sphere", "--data", str(tmp_path / "nowhere")]) == 2
    assert "sphere data folder not found" in capsys.readouterr().err


def test_rig_convert_bouguet_pair(sphere_dir, tmp_path, capsys):
    out = tmp_path / "rig.yaml"
    assert main(["rig", "convert", "--camera", str(sphere_dir / "CamCalibResult_real.mat"),
                 "--projector", str(sphere_dir / "PrjCalibResult_real.mat"), "--out", str(out)]) == 0
    rig = load_rig(out)
    assert rig.camera.size == (640, 480) and rig.projector.size == (912, 1140)
    assert abs(rig.camera.K[0, 0] - 2592.156) < 1e-3
    opencv = tmp_path / "rig.yml"
    assert main(["rig", "convert", "--camera", str(sphere_dir / "CamCalibResult_real.mat"),
                 "--projector", str(sphere_dir / "PrjCalibResult_real.mat"), "--to", "opencv",
                 "--out", str(opencv)]) == 0
    again = tmp_path / "again.yaml"
    assert main(["rig", "convert", "--opencv-rig", str(opencv), "--out", str(again)]) == 0
    np.testing.assert_allclose(load_rig(again).projector.T, rig.projector.T, atol=1e-9)
    refined = tmp_path / "refined.yaml"
    assert main(["rig", "convert", "--camera", str(sphere_dir / "CamCalibResult_real.mat"),
                 "--projector", str(sphere_dir / "PrjCalibResult_real.mat"), "--relative-pose", "all-views",
                 "--out", str(refined)]) == 0
    moved_mm = np.linalg.norm(load_rig(refined).projector.center - rig.projector.center)
    assert 1.0 < moved_mm < 10.0


def test_rig_convert_missing_projector_is_exit_2(tmp_path, capsys):
    assert main(["rig", "convert", "--camera", "cam.mat", "--out", str(tmp_path / "x.yaml")]) == 2
    assert "--camera needs --projector" in capsys.readouterr().err
