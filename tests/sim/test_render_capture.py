import numpy as np
import pytest

from dptpu.cli.main import main
from dptpu.fpp.calibration import load_rig
from dptpu.fpp.capture import load_ground_truth, load_reference, load_sequence_images, read_capture
from dptpu.fpp.reconstruct import unwrap_capture
from dptpu.sim.image_formation import parse_sequences
from dptpu.sim.render import render_capture
from dptpu.sim.scenes import load_scene

#: Bound on |decoded - true| projector x of a noiseless 8-bit 12-step render, MF 96/1 (docs/twin.md): the 8-bit
#: quantization noise (0.29 DN) over a modulation of ~90 DN gives 0.002 px RMS on the plane.
DECODE_BOUND_PX = {"plane": 0.01, "sphere": 0.03}


def _assert_orders_agree(decoded_order, true_order, true_coord, frequency, extent, bound_px):
    """Fringe orders agree except where the true coordinate lies within the decoding bound of a fringe boundary
    (there a correct decode may land on either side: the absolute phase is right, the order +-1)."""
    period = extent / frequency
    distance = np.abs(true_coord / period - np.round(true_coord / period)) * period
    away = distance > bound_px
    np.testing.assert_array_equal(decoded_order[away], true_order[away])
    assert np.all(np.abs(decoded_order - true_order) <= 1)


@pytest.fixture(scope="module")
def captures(tmp_path_factory, small_rig):
    out = {}
    for name in ("plane", "sphere"):
        folder = tmp_path_factory.mktemp(name)
        render_capture(small_rig, load_scene(name, small_rig), parse_sequences("96x12,1x12,white"), folder)
        out[name] = read_capture(folder)
    return out


def test_capture_folder_holds_frames_calibration_and_ground_truth(captures, small_rig):
    capture = captures["sphere"]
    assert capture.camera_size == (160, 120) and capture.projector_size == (912, 1140)
    assert [s.frequency for s in capture.phase_sequences] == [96.0, 1.0]
    assert load_sequence_images(capture, capture.phase_sequences[0]).shape == (12, 120, 160)
    assert load_reference(capture, "white").max() > 100
    rig = load_rig(capture.calibration)
    np.testing.assert_allclose(rig.camera.K, small_rig.camera.K)
    np.testing.assert_allclose(rig.projector.T, small_rig.projector.T)
    assert capture.ground_truth.name == "gt.npz"
    gt = np.load(capture.ground_truth)
    for key, shape in (("projector_x", (120, 160)), ("projector_y", (120, 160)), ("depth", (120, 160)),
                       ("normals", (120, 160, 3)), ("valid", (120, 160)), ("fringe_order_96", (120, 160)),
                       ("fringe_order_1", (120, 160))):
        assert gt[key].shape == shape, key
    assert load_ground_truth(capture).valid.sum() == gt["valid"].sum() > 1000


@pytest.mark.parametrize("name", ["plane", "sphere"])
def test_ground_truth_fringe_orders_agree_with_projector_x(captures, name):
    gt = np.load(captures[name].ground_truth)
    valid = gt["valid"]
    x = gt["projector_x"][valid].astype(np.float64)
    np.testing.assert_array_equal(gt["fringe_order_96"][valid], np.floor(96 * x / 912))
    assert np.all(gt["fringe_order_1"][valid] == 0)
    assert np.all(gt["fringe_order_96"][~valid] == -1) and np.all(np.isnan(gt["projector_x"][~valid]))


@pytest.mark.parametrize("name", ["plane", "sphere"])
def test_decoding_a_noiseless_render_recovers_projector_x(captures, name):
    capture = captures[name]
    # the render's decoding, not the phase-noise test: that one drops the sphere's rim (modulation ~10 DN, under a
    # fifth of the median 68), where the 8-bit quantization alone is 5x the scan's median phase noise (2 % of it)
    result = unwrap_capture(capture, method="mf", max_noise_ratio=0)
    gt = np.load(capture.ground_truth)
    both = result.valid & gt["valid"]
    assert both.sum() > 0.98 * gt["valid"].sum()
    _assert_orders_agree(result.fringe_order[both], gt["fringe_order_96"][both], gt["projector_x"][both], 96, 912,
                         DECODE_BOUND_PX[name])
    decoded = result.absolute_phase * 912 / (2 * np.pi * 96)
    error = decoded[both] - gt["projector_x"][both]
    assert np.abs(error).max() < DECODE_BOUND_PX[name]
    assert abs(error.mean()) < 0.1 * DECODE_BOUND_PX[name]  # no bias: pixel-centre conventions agree


def test_render_capture_rejects_mixed_axes(tmp_path, small_rig):
    with pytest.raises(ValueError, match="one fringe_axis"):
        render_capture(small_rig, load_scene("plane", small_rig), parse_sequences("16x3,16x3:y"), tmp_path)
    with pytest.raises(ValueError, match="engine must be one of raycast, blender"):
        render_capture(small_rig, load_scene("plane", small_rig), parse_sequences("16x3"), tmp_path, engine="pov")


def test_cli_sim_render_writes_a_capture_with_effects(tmp_path, capsys):
    effects = tmp_path / "effects.yaml"
    effects.write_text("effects:\n  - projector_gamma: {gamma: 2.0}\n  - sensor_noise\n")
    out = tmp_path / "capture"
    code = main(["sim", "render", "--rig", "nominal", "--scene", "board", "--sequence", "16x4,1x4",
                 "--size", "160x120", "--effects", str(effects), "--seed", "2", "--out", str(out)])
    assert code == 0
    capture = read_capture(out)
    assert capture.extras["twin"]["effects"][0] == {"projector_gamma": {"gamma": 2.0}}
    assert [list(e)[0] for e in load_rig(capture.calibration).effects] == ["projector_gamma", "sensor_noise"]


def test_cli_sim_render_bad_scene_is_exit_code_2(tmp_path, capsys):
    scene = tmp_path / "bad.yaml"
    scene.write_text("objects:\n  - {shape: sphere, radius: 10, material: {albedo: 1.5}}\n")
    code = main(["sim", "render", "--rig", "nominal", "--scene", str(scene), "--size", "160x120",
                 "--out", str(tmp_path / "out")])
    assert code == 2
    assert "bad.yaml: objects[0].material.albedo: material albedo must be in [0.0, 1.0]; got 1.5" in \
        capsys.readouterr().err


def test_horizontal_fringe_capture_decodes_to_projector_y(tmp_path, small_rig):
    render_capture(small_rig, load_scene("plane", small_rig), parse_sequences("64x12:y,1x12:y"), tmp_path)
    capture = read_capture(tmp_path)
    assert capture.fringe_axis == "y"
    # the render's decoding, not the phase-noise test: that one drops the sphere's rim (modulation ~10 DN, under a
    # fifth of the median 68), where the 8-bit quantization alone is 5x the scan's median phase noise (2 % of it)
    result = unwrap_capture(capture, method="mf", max_noise_ratio=0)
    gt = np.load(capture.ground_truth)
    both = result.valid & gt["valid"]
    assert both.sum() > 0.98 * gt["valid"].sum()
    _assert_orders_agree(result.fringe_order[both], gt["fringe_order_64"][both], gt["projector_y"][both], 64, 1140,
                         0.02)
    decoded = result.absolute_phase * 1140 / (2 * np.pi * 64)
    assert np.abs(decoded[both] - gt["projector_y"][both]).max() < 0.02


def test_supersampled_capture_integrates_pixels_and_keeps_the_phase(tmp_path, small_rig):
    from dptpu.sim.raycast import trace
    from dptpu.sim.scenes.scene import posed_mesh

    plane = load_scene("plane", small_rig).meshes[0]
    square = posed_mesh("square", np.array([[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]], float),
                        [[0, 2, 1], [0, 3, 2]], translation=[0.0, 0.0, 700.0])
    render_capture(small_rig, [plane, square], parse_sequences("96x12,1x12,white"), tmp_path, supersample=3)
    capture = read_capture(tmp_path)
    assert capture.extras["twin"]["supersample"] == 3
    # the white frame is the 3x3 box average of the white frame traced at 3x the resolution
    from dptpu.sim.image_formation import quantize, reflectance_factor
    from dptpu.sim.rig import resize_camera

    fine_rig = resize_camera(small_rig, (480, 360))
    fine = reflectance_factor(fine_rig, trace(fine_rig, [plane, square]))
    expected = quantize(255 * fine.reshape(120, 3, 160, 3).mean(axis=(1, 3)))
    np.testing.assert_array_equal(load_reference(capture, "white"), expected)
    # pixels straddling the square's edge and shadow mix levels; elsewhere the phase is the pixel centre's
    result = unwrap_capture(capture, method="mf")
    gt = np.load(capture.ground_truth)
    mixed = (expected != quantize(255 * reflectance_factor(small_rig, trace(small_rig, [plane, square]))))
    assert mixed.sum() > 20
    from scipy.ndimage import binary_dilation

    interior = result.valid & gt["valid"] & ~binary_dilation(mixed | ~gt["valid"], iterations=2)
    decoded = result.absolute_phase * 912 / (2 * np.pi * 96)
    error = decoded[interior] - gt["projector_x"][interior]
    assert interior.sum() > 0.7 * gt["valid"].sum()
    assert np.abs(error).max() < 0.02
