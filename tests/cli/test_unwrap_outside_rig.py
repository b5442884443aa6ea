"""``dptpu unwrap`` / ``dptpu triangulate`` by default on a noisy capture of a rig unlike the project's own: the network
is applied (the gate reads the wrapped phase, not the classical orders), low confidence and depth edges dropped."""
import numpy as np
import pytest

from dptpu.cli.main import main
from dptpu.fpp.calibration import save_rig
from dptpu.fpp.capture import PhaseFrames, write_capture
from dptpu.models.inference import shipped_model_path
from tests.mixed_pixel_rigs import PROJECTOR_SIZE, OutsideRig, default_scene, render

pytestmark = pytest.mark.skipif(shipped_model_path() is None, reason="no shipped model models/dptpu.onnx")


@pytest.fixture(scope="module")
def noisy_mw_capture(tmp_path_factory):
    """MW 96/95, 3 steps, the paper's 2 sigma (3.1386 DN): the classical order is wrong on ~45 % of the pixels."""
    outside = OutsideRig(camera_focal_px=700.0)  # fringe periods of 4.4 camera pixels: within the model's domain
    capture = render(outside, default_scene(outside, seed=0), [96.0, 95.0], steps=3, noise_dn=3.1386, seed=0,
                     amplitude_dn=80.0, offset_dn=100.0)  # a darker scene than the default
    folder = tmp_path_factory.mktemp("outside")
    rig_file = save_rig(capture.rig, folder / "rig.yaml")
    write_capture(folder / "capture", sequences=[PhaseFrames(capture.frames[f], frequency=f) for f in (96.0, 95.0)],
                  projector_size=PROJECTOR_SIZE, calibration=rig_file)
    return folder / "capture", capture


def _accuracy(out, capture, valid_key="valid"):
    with np.load(out) as result:
        valid = result[valid_key] & capture.pure
        truth = 2 * np.pi * 96.0 * capture.projector_x / PROJECTOR_SIZE[0]
        right = np.abs(result["absolute_phase"] - truth) < np.pi
        return float(right[valid].mean()), int(valid.sum()), str(result["model"])


def test_unwrap_applies_the_network_by_default_where_the_classical_order_fails(noisy_mw_capture, tmp_path, capsys):
    folder, capture = noisy_mw_capture
    assert main(["unwrap", "--capture", str(folder), "--method", "mw", "--model", "none", "--min-confidence", "0",
                 "--out", str(tmp_path / "classical.npz")]) == 0
    classical, _, _ = _accuracy(tmp_path / "classical.npz", capture)
    capsys.readouterr()
    assert classical < 0.6  # the classical order is wrong on > 40 % of the pure pixels

    assert main(["unwrap", "--capture", str(folder), "--method", "mw", "--out", str(tmp_path / "default.npz")]) == 0
    stdout = capsys.readouterr().out
    accuracy, kept, model = _accuracy(tmp_path / "default.npz", capture)
    assert model == str(shipped_model_path())
    # measured: 100.00 % of the kept pure pixels right, 98.3 % of them kept (docs/nodes.md "Confidence")
    assert accuracy >= 0.999 and kept >= 0.95 * capture.pure.sum()
    dropped = int(stdout.split(" pixels below the confidence threshold dropped")[0].rsplit("; ", 1)[1])
    assert dropped > 0


def test_triangulate_applies_the_same_model_and_drops_edges(noisy_mw_capture, tmp_path, capsys):
    import open3d as o3d

    folder, capture = noisy_mw_capture
    out = tmp_path / "cloud.ply"
    assert main(["triangulate", "--capture", str(folder), "--method", "mw", "--no-distortion", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert f"model {shipped_model_path()}" in stdout and "points at depth edges dropped" in stdout
    points = 1000.0 * np.asarray(o3d.io.read_point_cloud(str(out)).points)  # (M, 3) m in the file -> mm; world =
    # camera frame here
    off = capture.scene.distance_mm(points) > 1.0
    assert off.mean() <= 0.001  # measured 0.0 - 0.03 % on five outside rigs (docs/nodes.md)
    assert points.shape[0] >= 0.95 * capture.pure.sum()
