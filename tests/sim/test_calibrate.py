"""Calibration round trip in the twin: board poses rendered with vertical and horizontal fringes -> rig."""
import numpy as np
import pytest
import yaml

from dptpu.cli.main import main
from dptpu.fpp.calibration import load_rig
from dptpu.fpp.capture import read_capture
from dptpu.fpp.rig_calibration import calibrate_from_folders
from dptpu.fpp.stereo_calibration import project
from dptpu.sim.calibrate import DEFAULT_BOARD, board_poses, compare_with_truth, render_calibration_poses
from dptpu.sim.rig import nominal_rig

SIZE = (320, 240)  # the nominal rig's 640x480 camera, K scaled by 1/2 (fx = 1300 px)
POSES = 8


@pytest.fixture(scope="module")
def twin_rig():
    return nominal_rig(camera_size=SIZE)


@pytest.fixture(scope="module")
def pose_folders(twin_rig, tmp_path_factory):
    return render_calibration_poses(twin_rig, tmp_path_factory.mktemp("calib"), count=POSES, frequency=16,
                                    steps=4, supersample=2)


def test_board_poses_keep_the_whole_board_in_view_and_tilted(twin_rig):
    poses = board_poses(twin_rig, DEFAULT_BOARD, 8, seed=3)
    normals = []
    for R, T in poses:
        corners = project(twin_rig.camera, DEFAULT_BOARD.object_points() @ R.T + T)
        assert corners.min() >= 0 and corners[:, 0].max() < SIZE[0] and corners[:, 1].max() < SIZE[1]
        normals.append(R[:, 2])
    tilt_deg = np.degrees(np.arccos(np.abs(np.array(normals) @ [0, 0, 1.0])))
    assert tilt_deg.min() >= 20 - 1e-9 and tilt_deg.max() <= 40 + 1e-9


def test_board_poses_reject_a_board_too_big_for_the_view(twin_rig):
    from dptpu.fpp.rig_calibration import Board

    with pytest.raises(ValueError, match="does not fit the camera's view"):
        board_poses(twin_rig, Board(10, 8, 40.0), 4)


def test_pose_folders_hold_x_and_y_captures_with_white_references(pose_folders):
    assert len(pose_folders) == POSES
    for axis in ("x", "y"):
        capture = read_capture(pose_folders[0] / axis)
        assert capture.fringe_axis == axis
        assert capture.camera_size == SIZE and capture.projector_size == (912, 1140)
        assert sorted(capture.frequency_of(s) for s in capture.phase_sequences) == [1.0, 16.0]
        assert "white" in capture.references


def test_round_trip_recovers_focal_lengths_and_baseline(twin_rig, pose_folders):
    result = calibrate_from_folders(pose_folders, DEFAULT_BOARD)
    report = compare_with_truth(result, twin_rig)
    # the bounds; measured 0.19 % (camera), 0.22 % (projector), 0.14 mm
    assert report["camera"]["focal_error_percent"] < 0.5
    assert report["projector"]["focal_error_percent"] < 0.5
    assert report["baseline_mm"]["error_mm"] < 1.0
    assert report["rotation_error_deg"] < 0.3
    assert report["camera"]["rms_px"] < 0.2 and report["projector"]["rms_px"] < 0.4


def test_cli_calibrates_pose_folders_and_prints_errors_per_device(pose_folders, tmp_path, capsys):
    out = tmp_path / "rig.yaml"
    code = main(["calibrate", str(pose_folders[0].parent), "--board", "10x8:13", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "reprojection RMS: camera" in text and "projector" in text and "pose_07" in text
    rig = load_rig(out)
    summary = text.strip().splitlines()[-1]  # ends with one human line: poses, file, both RMS, baseline
    result = calibrate_from_folders([pose_folders[0].parent], DEFAULT_BOARD)
    assert summary == (f"calibrated {len(pose_folders)} poses -> {out}: RMS camera {result.camera.rms_px:.3f} px, "
                       f"projector {result.projector.rms_px:.3f} px; baseline {result.baseline_mm:.1f} mm")
    assert yaml.safe_load(out.read_text())["format"] == "dptpu-rig/1"
    assert rig.camera.size == SIZE and rig.projector.size == (912, 1140)
    np.testing.assert_allclose(rig.camera.R, np.eye(3))


def test_cli_names_the_pose_folder_when_the_board_is_wrong(pose_folders, tmp_path, capsys):
    code = main(["calibrate", str(pose_folders[0]), str(pose_folders[1]), str(pose_folders[2]),
                 "--board", "9x6:13", "--out", str(tmp_path / "rig.yaml")])
    assert code == 2
    assert "pose_00: no 9x6 checkerboard corners found" in capsys.readouterr().err


def test_cli_rejects_missing_folders_and_too_few_poses(pose_folders, tmp_path, capsys):
    assert main(["calibrate", str(tmp_path / "nope"), "--board", "10x8:13", "--out", str(tmp_path / "r.yaml")]) == 2
    assert "nope: no such calibration pose folder" in capsys.readouterr().err
    assert main(["calibrate", str(pose_folders[0]), "--board", "10x8:13", "--out", str(tmp_path / "r.yaml")]) == 2
    assert "at least 3 board poses" in capsys.readouterr().err


def test_cli_twin_round_trip_prints_the_comparison(tmp_path, capsys):
    out = tmp_path / "rig.yaml"
    code = main(["calibrate", "--twin", "--rig", "nominal", "--size", "160x120", "--poses", "3", "--supersample", "1",
                 "--board", "10x8:13", "--keep", str(tmp_path / "poses"), "--out", str(out)])
    assert code == 0
    captured = capsys.readouterr()
    text = captured.out
    assert "camera: fx" in text and "baseline:" in text and "relative pose error" in text
    assert text.strip().splitlines()[-1].startswith(f"calibrated 3 poses -> {out}: RMS camera ")
    assert "against the twin: baseline error" in text.strip().splitlines()[-1]
    assert "rendering poses: 100%" in captured.err and "observing poses: 100%" in captured.err  # tqdm bars
    code = main(["calibrate", "--twin", "--rig", "nominal", "--size", "160x120", "--poses", "3", "--supersample", "1",
                 "--board", "10x8:13", "--out", str(tmp_path / "scratch.yaml"), "--quiet"])
    captured = capsys.readouterr()  # without --keep, the deleted temporary folder is named nowhere
    assert code == 0 and "dptpu-calibrate-" not in captured.out + captured.err and "%|" not in captured.err
    assert sorted(p.name for p in (tmp_path / "poses").iterdir()) == ["pose_00", "pose_01", "pose_02"]
    assert load_rig(out).camera.size == (160, 120)
    capsys.readouterr()
    assert main(["calibrate", str(tmp_path / "poses"), "--twin", "--rig", "nominal", "--board", "10x8:13",
                 "--out", str(out)]) == 2
    assert "either POSE_DIRs or --twin --rig RIG" in capsys.readouterr().err
    assert main(["calibrate", "--twin", "nominal", "--board", "10x8:13", "--out", str(out)]) == 2  # the old spelling
    assert capsys.readouterr().err == ("dptpu calibrate: error: --twin takes no value now: write --twin --rig nominal "
                                       "(one name for a rig file in every command)\n")
