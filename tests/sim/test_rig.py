import numpy as np
import pytest

from dptpu.fpp.calibration import save_opencv_rig, save_rig
from dptpu.fpp.distortion import distort, normalized_to_pixels
from dptpu.fpp.measured_data import shared_data_dir
from dptpu.sim.rig import load_twin_rig, nominal_rig, resize_camera, working_distance, working_point

SPHERE_DATA = shared_data_dir() / "dptpu-sphere"


def _project(device, points):
    local = points @ device.R.T + device.T
    return normalized_to_pixels(distort(local[:, :2] / local[:, 2:], device.dist), device.K)


def test_nominal_rig_axes_cross_at_working_distance():
    rig = nominal_rig()
    np.testing.assert_allclose(working_point(rig), [0.0, 0.0, 800.0], atol=1e-9)
    assert working_distance(rig) == pytest.approx(800.0)
    # the working point projects onto both principal points
    np.testing.assert_allclose(_project(rig.camera, working_point(rig)[None])[0], rig.camera.K[:2, 2], atol=1e-9)
    np.testing.assert_allclose(_project(rig.projector, working_point(rig)[None])[0], rig.projector.K[:2, 2],
                               atol=1e-9)


def test_convention_resize_keeps_outer_edges_of_the_image():
    rig = nominal_rig()
    small = resize_camera(rig, (160, 120))
    assert small.camera.size == (160, 120)
    points = np.random.default_rng(0).uniform([-80, -60, 700], [80, 60, 900], (50, 3))
    full, reduced = _project(rig.camera, points), _project(small.camera, points)
    np.testing.assert_allclose(reduced, (full + 0.5) * 0.25 - 0.5, atol=1e-9)


@pytest.mark.parametrize("writer", [save_rig, save_opencv_rig])
def test_load_twin_rig_reads_rig_files(tmp_path, writer):
    rig = nominal_rig()
    path = writer(rig, tmp_path / "rig.yaml")
    loaded = load_twin_rig(path, size="320x240")
    assert loaded.camera.size == (320, 240)
    np.testing.assert_allclose(loaded.projector.K, rig.projector.K)
    np.testing.assert_allclose(loaded.projector.R, rig.projector.R, atol=1e-12)
    np.testing.assert_allclose(loaded.camera.K[0, 0], rig.camera.K[0, 0] / 2)


def test_load_twin_rig_bad_sources_name_the_problem(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such rig file"):
        load_twin_rig(tmp_path / "missing.yaml")
    with pytest.raises(ValueError, match="CAM.mat,PRJ.mat"):
        load_twin_rig("a.mat,")
    with pytest.raises(ValueError, match="WIDTHxHEIGHT"):
        load_twin_rig("nominal", size="160by120")


@pytest.mark.skipif(not SPHERE_DATA.is_dir(), reason="needs ../shared/data/dptpu-sphere (the paper's calibration)")
def test_load_twin_rig_reads_a_bouguet_pair_with_the_dptpu_sizes():
    source = f"{SPHERE_DATA / 'CamCalibResult_sim.mat'},{SPHERE_DATA / 'PrjCalibResult_sim.mat'}"
    rig = load_twin_rig(source)
    assert rig.camera.size == (640, 480) and rig.projector.size == (912, 1140)
    pair = load_twin_rig((SPHERE_DATA / "CamCalibResult_sim.mat", SPHERE_DATA / "PrjCalibResult_sim.mat"))
    np.testing.assert_allclose(pair.camera.K, rig.camera.K)
    # the published twin rig looks at a point ~0.83 m in front of the camera (the sphere data's distance)
    assert 780 < working_distance(rig) < 880
