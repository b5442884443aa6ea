import numpy as np
import pytest
from scipy.io import savemat

from dptpu.fpp.calibration import (
    DeviceModel,
    Rig,
    load_bouguet,
    load_bouguet_pair,
    load_opencv_device,
    load_opencv_rig,
    load_rig,
    save_opencv_rig,
    save_rig,
)
from tests.fpp.rig_fixtures import synthetic_rig

SPHERE_FILES = ["CamCalibResult_real.mat", "PrjCalibResult_real.mat", "CamCalibResult_sim.mat",
                "PrjCalibResult_sim.mat"]


@pytest.mark.parametrize("name", SPHERE_FILES)
def test_the_four_bouguet_files_load(sphere_dir, name):
    device = load_bouguet(sphere_dir / name, None)
    expected_size = (640, 480) if name.startswith("Cam") else (912, 1140)
    assert device.size == expected_size  # from the toolbox's nx, ny
    assert 1700 < device.K[0, 0] < 2700 and device.K[2, 2] == 1
    assert abs(np.linalg.det(device.R) - 1) < 1e-9
    assert 790 < device.T[2] < 860  # mm: calibration pose 1 lies about 0.8 m from both devices


def test_real_rig_geometry_from_the_calibration(sphere_dir):
    # The calibration, not the paper's text, is the rig: the paper states a 0.17 m baseline and 6.21 deg between
    # the optical axes; the real Bouguet pair gives 135.8 mm and 8.99 deg (docs/real-sphere.md), and the twin's
    # calibration agrees with it to about 1 mm and 0.05 deg.
    geometry = {}
    for kind in ("real", "sim"):
        rig = load_bouguet_pair(sphere_dir / f"CamCalibResult_{kind}.mat", sphere_dir / f"PrjCalibResult_{kind}.mat")
        geometry[kind] = (np.linalg.norm(rig.camera.center - rig.projector.center),
                          np.degrees(np.arccos(rig.camera.R[2] @ rig.projector.R[2])))
    assert abs(geometry["real"][0] - 135.84) < 0.01 and abs(geometry["real"][1] - 8.987) < 0.001
    assert abs(geometry["sim"][0] - geometry["real"][0]) < 1.5
    assert abs(geometry["sim"][1] - geometry["real"][1]) < 0.1


def write_bouguet(path, **fields):
    base = {"KK": np.array([[2600.0, 0, 320], [0, 2600, 240], [0, 0, 1]]), "kc": np.zeros((5, 1)),
            "Rc_1": np.eye(3), "Tc_1": np.array([[0.0], [0.0], [800.0]]), "nx": 640, "ny": 480}
    base.update(fields)
    savemat(str(path), {k: v for k, v in base.items() if v is not None})
    return path


def test_missing_field_names_file_and_field(tmp_path):
    path = write_bouguet(tmp_path / "cam.mat", kc=None)
    with pytest.raises(ValueError, match=r"cam\.mat: missing field 'kc'"):
        load_bouguet(path, None)


def test_wrong_shape_names_file_and_field(tmp_path):
    path = write_bouguet(tmp_path / "cam.mat", KK=np.eye(2))
    with pytest.raises(ValueError, match=r"cam\.mat: field 'KK' must have shape \(3, 3\); got \(2, 2\)"):
        load_bouguet(path, None)


def test_corrupt_file_names_the_file(tmp_path):
    path = tmp_path / "broken.mat"
    path.write_bytes(b"MATLAB 5.0 MAT-file" + bytes(range(256)) * 3)
    with pytest.raises(ValueError, match=r"broken\.mat: not a readable MATLAB \.mat file"):
        load_bouguet(path, None)
    with pytest.raises(FileNotFoundError, match="absent.mat"):
        load_bouguet(tmp_path / "absent.mat", None)


def assert_same_rig(a: Rig, b: Rig):
    for da, db in ((a.camera, b.camera), (a.projector, b.projector)):
        for name in ("K", "dist", "R", "T"):
            np.testing.assert_allclose(getattr(da, name), getattr(db, name), atol=1e-12)
        assert da.size == db.size
    assert a.units == b.units


def test_dptpu_rig_yaml_round_trip(tmp_path):
    rig = synthetic_rig()
    assert_same_rig(load_rig(save_rig(rig, tmp_path / "rig.yaml")), rig)


def test_opencv_rig_round_trip(tmp_path):
    rig = synthetic_rig()
    path = save_opencv_rig(rig, tmp_path / "rig.yml")
    assert_same_rig(load_rig(path), rig)  # load_rig detects the OpenCV format
    assert_same_rig(load_opencv_rig(path), rig)


def test_opencv_single_device_file(tmp_path):
    import cv2

    path = tmp_path / "camera.yml"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", 640)
    storage.write("image_height", 480)
    storage.write("camera_matrix", np.array([[2600.0, 0, 320], [0, 2600, 240], [0, 0, 1]]))
    storage.write("distortion_coefficients", np.array([[-0.1, 0.2, 0.001, 0.002, 0.0]]))
    storage.write("rvec", np.array([[0.0], [0.1], [0.0]]))
    storage.write("tvec", np.array([[1.0], [2.0], [3.0]]))
    storage.release()
    device = load_opencv_device(path)
    assert device.size == (640, 480)
    np.testing.assert_allclose(device.dist, [-0.1, 0.2, 0.001, 0.002, 0.0])
    np.testing.assert_allclose(device.R[0, 2], np.sin(0.1), atol=1e-12)
    np.testing.assert_allclose(device.T, [1, 2, 3])


def test_rig_yaml_errors_name_the_problem(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text("format: dptpu-rig/1\ncamera: {size: [640, 480], K: [[1,0,0],[0,1,0],[0,0,1]], dist: [0,0,0,0,0],"
                    " R: [[1,0,0],[0,1,0],[0,0,1]]}\nprojector: {}\n")
    with pytest.raises(ValueError, match=r"rig\.yaml: camera: missing key 'T'"):
        load_rig(path)
    path.write_text("format: something-else\n")
    with pytest.raises(ValueError, match="format must be 'dptpu-rig/1'"):
        load_rig(path)


def test_device_model_checks():
    with pytest.raises(ValueError, match="R must be a rotation"):
        DeviceModel(K=np.eye(3), dist=np.zeros(5), R=2 * np.eye(3), T=np.zeros(3), size=(10, 10))
    with pytest.raises(ValueError, match=r"K must have shape \(3, 3\); got \(2, 2\)"):
        DeviceModel(K=np.eye(2), dist=np.zeros(5), R=np.eye(3), T=np.zeros(3), size=(10, 10))
