"""``dptpu unwrap`` and ``dptpu triangulate`` in-process: outputs, and exit code 2 with one line for bad input.

(The triangulate sub-command is tested here too: it shares the capture reading and unwrapping options.)
"""
import re
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import yaml

from dptpu.cli.main import main
from dptpu.cli.unwrap_cmd import NPZ_KEYS
from dptpu.fpp.calibration import DeviceModel, Rig, save_rig

MF = [{"frequency": 64}, {"frequency": 1}]


def _run(capsys, argv):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _edit_yaml(folder, edit):
    path = folder / "capture.yaml"
    document = yaml.safe_load(path.read_text())
    edit(document)
    path.write_text(yaml.safe_dump(document, sort_keys=False))


# --------------------------------------------------------------------------------------------------
# unwrap
# --------------------------------------------------------------------------------------------------

def test_unwrap_writes_every_key_and_prints_the_valid_count(synthetic_capture, tmp_path, capsys):
    folder, scene = synthetic_capture(MF)
    out = tmp_path / "phase.npz"

    code, stdout, stderr = _run(capsys, ["unwrap", "--capture", str(folder), "--method", "mf", "--out", str(out)])

    assert code == 0 and stderr == ""
    with np.load(out) as result:
        assert set(result.files) == set(NPZ_KEYS)
        height, width = scene.lit.shape
        for key in ("fringe_order", "absolute_phase", "valid", "modulation", "reliability"):
            assert result[key].shape == (height, width)
        assert result["valid"].dtype == bool and result["fringe_order"].dtype == np.int32
        assert float(result["frequency"]) == 64.0
        assert str(result["fringe_axis"]) == "x" and str(result["method"]) == "mf"
        assert result["projector_size"].tolist() == [912, 1140]
        count = int(result["valid"].sum())
    assert count == scene.lit.sum()  # every lit pixel of the synthetic scene, none of the shadow
    assert stdout.strip().startswith(f"mf: {count} of {height * width} pixels valid "
                                     f"({100 * count / (height * width):.1f}%), frequency 64; model ")
    assert stdout.strip().endswith(f"; 0 pixels below the confidence threshold dropped -> {out}")


def test_unwrap_adds_the_npz_suffix(synthetic_capture, tmp_path, capsys):
    folder, _ = synthetic_capture(MF)
    code, stdout, _ = _run(capsys, ["unwrap", "--capture", str(folder), "--method", "mf", "--out", str(tmp_path / "x")])
    assert code == 0 and (tmp_path / "x.npz").is_file() and stdout.strip().endswith("x.npz")


def _drop_projector_size(folder):
    _edit_yaml(folder, lambda d: d["projector"].pop("size"))


def _drop_one_image(folder):
    _edit_yaml(folder, lambda d: d["sequences"][0]["images"].pop())


def _zero_frequency(folder):
    _edit_yaml(folder, lambda d: d["sequences"][1].update(frequency=0))


def _sixteen_bit_frame(folder):
    cv2.imwrite(str(folder / "seq0_f64_s02.png"), np.full((60, 80), 1000, np.uint16))


def _smaller_frame(folder):
    cv2.imwrite(str(folder / "seq1_f1_s07.png"), np.zeros((30, 40), np.uint8))


def _delete_frame(folder):
    (folder / "seq1_f1_s00.png").unlink()


@pytest.mark.parametrize("damage, message", [
    (_drop_projector_size, r"capture\.yaml: missing key 'projector\.size'"),
    (_drop_one_image, r"sequence 0 \(frequency 64\): 11 images listed but steps is 12"),
    (_zero_frequency, r"sequences\[1\]\.frequency must be > 0; got 0"),
    (_sixteen_bit_frame, r"seq0_f64_s02\.png is a 16-bit image, camera\.bit_depth is 8"),
    (_smaller_frame, r"seq1_f1_s07\.png is 40x30, camera\.size is 80x60"),
    (_delete_frame, r"1 listed file\(s\) do not exist: seq1_f1_s00\.png"),
])
def test_bad_capture_exits_2_with_one_line_on_stderr(synthetic_capture, tmp_path, capsys, damage, message):
    folder, _ = synthetic_capture(MF)
    damage(folder)
    out = tmp_path / "phase.npz"

    code, stdout, stderr = _run(capsys, ["unwrap", "--capture", str(folder), "--method", "mf", "--out", str(out)])

    assert code == 2
    assert stderr.startswith("dptpu unwrap: error: ")
    assert re.search(message, stderr), stderr
    assert "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1
    assert stdout == "" and not out.exists()


@pytest.mark.parametrize("extra, message", [
    (["--high", "50"], r"unknown frequency 50 \(--high\); the capture has phase sequences of frequency"),
    (["--method", "heterodyne", "--low", "1"], r"heterodyne unwraps with every frequency .*--low do not apply"),
])
def test_bad_choice_exits_2(synthetic_capture, tmp_path, capsys, extra, message):
    folder, _ = synthetic_capture(MF)
    argv = ["unwrap", "--capture", str(folder), "--method", "mf", "--out", str(tmp_path / "p.npz")] + extra
    code, _, stderr = _run(capsys, argv)
    assert code == 2 and re.search(message, stderr) and "Traceback" not in stderr


def test_missing_capture_folder_and_output_folder_exit_2(synthetic_capture, tmp_path, capsys):
    code, _, stderr = _run(capsys, ["unwrap", "--capture", str(tmp_path / "nope"), "--method", "mf",
                                    "--out", str(tmp_path / "p.npz")])
    assert code == 2 and "nope: no such capture folder or capture.yaml" in stderr

    folder, _ = synthetic_capture(MF)
    code, _, stderr = _run(capsys, ["unwrap", "--capture", str(folder), "--method", "mf",
                                    "--out", str(tmp_path / "missing" / "p.npz")])
    assert code == 2 and "output folder does not exist" in stderr


# --------------------------------------------------------------------------------------------------
# triangulate
# --------------------------------------------------------------------------------------------------

PLANE_Z_MM = 500.0


def _plane_rig_and_scene(shape=(60, 80)):
    """A camera at the world origin looking down +z, a projector 100 mm to its right; a plane z = 500 mm.

    Returns the rig and, per camera pixel, the projector column that sees the same point of the plane.
    """
    height, width = shape
    camera = DeviceModel(K=[[100.0, 0, (width - 1) / 2], [0, 100.0, (height - 1) / 2], [0, 0, 1]],
                         dist=np.zeros(5), R=np.eye(3), T=np.zeros(3), size=(width, height))
    projector = DeviceModel(K=[[800.0, 0, 555.5], [0, 800.0, 569.5], [0, 0, 1]], dist=np.zeros(5),
                            R=np.eye(3), T=[-100.0, 0, 0], size=(912, 1140))
    rows, cols = np.mgrid[0:height, 0:width].astype(float)
    x_mm = (cols - camera.K[0, 2]) / 100.0 * PLANE_Z_MM  # (H, W) world x of the plane point
    projector_x = 800.0 * (x_mm - 100.0) / PLANE_Z_MM + 555.5  # 75.5 .. 715.5
    scene = SimpleNamespace(projector_x=projector_x, albedo=np.full(shape, 0.9), lit=np.ones(shape, bool))
    return Rig(camera=camera, projector=projector, units="mm"), scene


def test_triangulate_writes_points_on_the_plane_in_metres_or_millimetres(synthetic_capture, tmp_path, capsys):
    import open3d as o3d

    rig, scene = _plane_rig_and_scene()  # a rig file in mm
    rig_file = save_rig(rig, tmp_path / "rig.yaml")
    folder, _ = synthetic_capture([{"period": 42}, {"period": 45}, {"period": 48}], scene=scene,
                                  calibration=rig_file)
    out, out_mm = tmp_path / "cloud.ply", tmp_path / "cloud_mm.ply"

    code, stdout, stderr = _run(capsys, ["triangulate", "--capture", str(folder), "--method", "heterodyne",
                                         "--out", str(out)])

    assert code == 0, stderr
    points = np.asarray(o3d.io.read_point_cloud(str(out)).points)  # (M, 3), metres: every cloud file of dptpu
    assert points.shape == (scene.lit.size, 3)
    assert stdout.strip() == (f"heterodyne: {scene.lit.size} points (m); model none; the shipped model does not serve "
                              f"method heterodyne; 0 pixels below the confidence threshold dropped; 0 points at depth "
                              f"edges dropped (0 flying, 0 beside a step, 0 modulation dips, 0 partly shadowed, "
                              f"0 isolated); 0 points on islands of a wrong order dropped -> {out}")
    # Phase noise ~0.002 rad at period 42 px is ~0.01 projector px, ~0.04 mm in depth here.
    assert np.abs(points[:, 2] - PLANE_Z_MM / 1000).max() < 0.5e-3
    assert points[:, 0].min() == pytest.approx(-0.1975, abs=0.5e-3)  # pixel column 0: (0 - 39.5) / 100 * 0.5 m
    assert points[:, 0].max() == pytest.approx(0.1975, abs=0.5e-3)

    code, stdout, stderr = _run(capsys, ["triangulate", "--capture", str(folder), "--method", "heterodyne",
                                         "--units", "mm", "--out", str(out_mm)])
    assert code == 0 and " points (mm);" in stdout, stderr
    np.testing.assert_allclose(np.asarray(o3d.io.read_point_cloud(str(out_mm)).points), 1000 * points, rtol=1e-9)


def test_triangulate_without_calibration_exits_2(synthetic_capture, tmp_path, capsys):
    folder, _ = synthetic_capture(MF)
    code, stdout, stderr = _run(capsys, ["triangulate", "--capture", str(folder), "--method", "mf",
                                         "--out", str(tmp_path / "cloud.ply")])
    assert code == 2 and stdout == ""
    assert "capture.yaml: no 'calibration' key; triangulate needs a rig file (dptpu-rig/1" in stderr
    assert "Traceback" not in stderr


def test_triangulate_rejects_a_rig_of_another_camera(synthetic_capture, tmp_path, capsys):
    rig, _ = _plane_rig_and_scene(shape=(30, 40))
    folder, _ = synthetic_capture(MF, calibration=save_rig(rig, tmp_path / "rig.yaml"))
    code, _, stderr = _run(capsys, ["triangulate", "--capture", str(folder), "--method", "mf",
                                    "--out", str(tmp_path / "cloud.ply")])
    assert code == 2 and "camera size is 40x30 but the capture's camera.size is 80x60" in stderr


def test_triangulate_help_states_the_units(capsys):
    with pytest.raises(SystemExit):
        main(["triangulate", "--help"])
    assert "in metres (--units mm: millimetres)" in " ".join(capsys.readouterr().out.split())


def test_a_plain_gray_code_keeps_its_pixels_near_code_edges_by_default(synthetic_capture, tmp_path, capsys):
    # its margin is the distance to a code edge, which a plain code's pixels near its edges keep small (19 % of the
    # pixels of a capture of this synthetic scene with noise below 0.2, all of them right): the default threshold for
    # graycode is 0; an explicit one still applies
    folder, scene = synthetic_capture([{"period": 16}, {"kind": "graycode", "bits": 6, "period": 16, "inverse": True}])
    code, stdout, stderr = _run(capsys, ["unwrap", "--capture", str(folder), "--method", "graycode",
                                         "--out", str(tmp_path / "g.npz")])
    assert code == 0, stderr
    assert "; 0 pixels below the confidence threshold dropped" in stdout
    code, stdout, _ = _run(capsys, ["unwrap", "--capture", str(folder), "--method", "graycode", "--min-confidence",
                                    "0.99", "--out", str(tmp_path / "g2.npz")])
    dropped = int(stdout.split(" pixels below the confidence threshold dropped")[0].rsplit("; ", 1)[1])
    assert code == 0 and dropped > 0.1 * scene.lit.sum()
    code, _, stderr = _run(capsys, ["unwrap", "--capture", str(folder), "--method", "graycode", "--min-confidence",
                                    "1.5", "--out", str(tmp_path / "g3.npz")])
    assert code == 2 and stderr.strip().endswith("--min-confidence must be in [0, 1]; got 1.5")
