"""The unwrap node in the in-process harness: PhaseMaps of the analytic plane in, AbsolutePhase out."""
from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from dptpu.fpp.frequency_consistency import frequency_consistency
from dptpu.fpp.tpu import unwrap_mf, unwrap_mf_float32
from dptpu.messages import AbsolutePhase, CameraInfo, Header, Image, PhaseMaps, ScanStatus, Time
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.plumbing import LATCHED_QOS
from dptpu.nodes.unwrap import UnwrapNode
from dptpu.nodes.unwrap.node import load_model
from tests.nodes.test_cloud_scene import plane_scene

NOISE_RAD = 0.005  # the phase node's measured RMS phase noise on this scene (test_phase_node.py)


@pytest.fixture(scope="module")
def scene():
    return plane_scene()


@pytest.fixture
def harness():
    with NodeHarness() as harness:
        yield harness


def phase_maps(scene, frequencies, *, sequence_id=1, seed=0, valid=None):
    """PhaseMaps of the plane: analytic wrapped phases + Gaussian noise of NOISE_RAD, re-wrapped."""
    rng = np.random.default_rng(seed)
    phases = np.stack([np.mod(scene.absolute_phase(f) + rng.normal(0, NOISE_RAD, scene.lit.shape), 2 * np.pi)
                       for f in frequencies]).astype(np.float32)
    phases[phases >= 2 * np.pi] = 0.0
    return PhaseMaps(header=Header(stamp=Time.from_ns(1_700_000_000_000_000_000), frame_id="scanner_optical_frame"),
                     sequence_id=sequence_id, fringe_axis="x", projector_width=912, projector_height=1140,
                     frequencies=np.asarray(frequencies, dtype=np.float64), phases=phases,
                     modulation=np.full(phases.shape, 80.0, np.float32),
                     valid=np.ones(scene.lit.shape, bool) if valid is None else valid)


def start(harness, **parameters):
    node = harness.start(UnwrapNode, **parameters)
    source = harness.publisher(PhaseMaps, "/scanner/phase")
    absolute = harness.collect(AbsolutePhase, "/scanner/absolute_phase")
    status = harness.collect(ScanStatus, "/scanner/status")
    harness.connect()
    return node, source, absolute, status


@pytest.mark.parametrize("method, frequencies", [
    ("mf", (16.0, 1.0)),
    ("mw", (16.0, 15.0)),
    ("nt", (16.0, 15.0)),
    ("heterodyne", (16.0, 15.0, 13.0)),   # beats 1, 2 -> 1
])
def test_every_method_recovers_the_absolute_phase_of_the_plane(harness, scene, method, frequencies):
    node, source, absolute, status = start(harness, method=method)
    source.publish(phase_maps(scene, frequencies, sequence_id=5))
    (result,) = harness.wait(absolute, 1)
    assert (result.sequence_id, result.method, result.frequency) == (5, method, 16.0)
    assert result.valid.all()
    truth = scene.absolute_phase(16.0)
    assert np.abs(result.absolute_phase - truth).max() < 6 * NOISE_RAD  # the right order at every pixel
    expected_order = np.floor(result.absolute_phase / (2 * np.pi)).astype(np.int32)
    assert np.array_equal(result.fringe_order, expected_order)
    assert result.reliability.min() > 0.5
    (ok,) = harness.wait(status, 1)
    assert (ok.level, ok.state, ok.valid_pixels, ok.total_pixels) == (ScanStatus.OK, "processing", 19200, 19200)


def test_invalid_pixels_stay_invalid_and_nan_pixels_marked_valid_are_counted(harness, scene):
    node, source, absolute, status = start(harness, method="mf")
    valid = np.ones(scene.lit.shape, bool)
    valid[:10] = False
    maps = phase_maps(scene, (16.0, 1.0), valid=valid)
    maps.phases[0, 50, :7] = np.nan
    source.publish(maps)
    (result,) = harness.wait(absolute, 1)
    assert not result.valid[:10].any() and np.isnan(result.absolute_phase[:10]).all()
    assert not result.valid[50, :7].any() and result.valid[50, 7:].all()
    (warn,) = harness.wait(status, 1)
    assert warn.level == ScanStatus.WARN and warn.reason == "7 pixels marked valid had NaN phase; treated as invalid"
    assert node.pixels_nan == 7 and warn.valid_pixels == 19200 - 1600 - 7


def test_scans_the_method_cannot_use_are_reported_and_the_node_goes_on(harness, scene):
    node, source, absolute, status = start(harness, method="mf", high_frequency=32.0)
    source.publish(phase_maps(scene, (16.0, 1.0), sequence_id=1))
    (failed,) = harness.wait(status, 1)
    assert (failed.level, failed.state) == (ScanStatus.ERROR, "failed")
    assert failed.reason == ("cannot unwrap scan 1 (mf): unknown frequency 32 (high_frequency); the scan has "
                             "frequencies 16, 1")
    maps = phase_maps(scene, (32.0, 1.0), sequence_id=2)
    maps.phases[1] = 7.0  # not a wrapped phase
    source.publish(maps)
    failed = harness.wait(status, 2)[1]
    assert "psi_l must be a wrapped phase in [0, 2*pi)" in failed.reason
    source.publish(phase_maps(scene, (32.0, 1.0), sequence_id=3))
    (result,) = harness.wait(absolute, 1)
    assert result.sequence_id == 3 and node.scans_rejected == 2 and node.scans_published == 1


def test_a_scan_of_another_size_than_the_camera_is_refused_before_it_is_unwrapped(harness, scene):
    """One 2000x2000 PhaseMaps used to leave the node at 4x its memory (issue 19): with the camera's CameraInfo a scan
    of any other size is refused with the reason, and the next right-sized scan is unwrapped."""
    node, source, absolute, status = start(harness, method="mf")
    height, width = scene.lit.shape
    info = harness.publisher(CameraInfo, "/camera/camera_info", LATCHED_QOS)
    info.publish(CameraInfo(height=height, width=width))
    harness.spin_until(lambda: node.camera_shape == (height, width), 10.0)
    big = PhaseMaps(header=Header(stamp=Time.from_ns(1), frame_id="scanner_optical_frame"), sequence_id=7,
                    fringe_axis="x", projector_width=912, projector_height=1140, frequencies=np.array([16.0, 1.0]),
                    phases=np.zeros((2, 400, 500), np.float32), modulation=np.zeros((2, 400, 500), np.float32),
                    valid=np.ones((400, 500), bool))
    source.publish(big)
    (failed,) = harness.wait(status, 1)
    assert (failed.sequence_id, failed.state) == (7, "failed")
    assert failed.reason == (f"cannot unwrap scan 7 (mf): the maps are 500x400 but /camera/camera_info says the "
                             f"camera is {width}x{height}; refused before unwrapping")
    source.publish(phase_maps(scene, (16.0, 1.0), sequence_id=8))
    (result,) = harness.wait(absolute, 1)
    assert result.sequence_id == 8 and node.scans_rejected == 1


def test_without_camera_info_max_pixels_bounds_the_scan(harness, scene):
    height, width = scene.lit.shape
    node, source, absolute, status = start(harness, method="mf", max_pixels=height * width - 1)
    source.publish(phase_maps(scene, (16.0, 1.0), sequence_id=1))
    (failed,) = harness.wait(status, 1)
    assert failed.reason == (f"cannot unwrap scan 1 (mf): the maps are {width}x{height} = {height * width} pixels, "
                             f"more than max_pixels {height * width - 1} (no CameraInfo has given the camera's "
                             f"size); refused before unwrapping")
    assert not absolute.messages


def test_the_unwrapped_frequencys_modulation_goes_out_as_the_clouds_intensity_image(harness, scene):
    node, source, absolute, _status = start(harness, method="mf", high_frequency=8.0)
    intensity = harness.collect(Image, "/scanner/intensity")
    harness.connect()
    maps = phase_maps(scene, (16.0, 1.0, 8.0), sequence_id=4)
    maps.modulation[2] = np.arange(19200, dtype=np.float32).reshape(120, 160)  # B of f = 8, the unwrapped one
    source.publish(maps)
    (result,) = harness.wait(absolute, 1)
    (image,) = harness.wait(intensity, 1)
    assert result.frequency == 8.0 and image.header == result.header == maps.header  # the scan's stamp
    assert image.encoding == "32FC1" and np.array_equal(image.to_array(), maps.modulation[2])


def test_a_heterodyne_scan_refuses_a_chosen_high_frequency(harness, scene):
    # heterodyne gives the highest frequency's phase: a chosen high one would be mislabelled
    node, source, absolute, status = start(harness, method="heterodyne", high_frequency=15.0)
    source.publish(phase_maps(scene, (16.0, 15.0, 13.0), sequence_id=1))
    (failed,) = harness.wait(status, 1)
    assert failed.reason.startswith("cannot unwrap scan 1 (heterodyne): heterodyne unwraps with every frequency and "
                                    "gives the highest; high_frequency and low_frequency do not apply to it")
    assert node.scans_rejected == 1


def test_bad_method_is_refused_with_the_choices(harness):
    with pytest.raises(ValueError, match="parameter method must be one of mf, mw, nt, heterodyne; got 'gray'"):
        harness.start(UnwrapNode, method="gray")


HAS_INFERENCE = importlib.util.find_spec("dptpu.models.inference") is not None


def test_model_without_the_inference_module_names_the_missing_module(tmp_path, monkeypatch):
    import dptpu.models

    # a build without the onnxruntime runner (or whose onnxruntime fails to import)
    monkeypatch.setitem(sys.modules, "dptpu.models.inference", None)
    monkeypatch.delattr(dptpu.models, "inference", raising=False)
    with pytest.raises(ImportError, match=r"needs the module dptpu\.models\.inference .* set model:=none"):
        load_model(str(tmp_path / "dptpu.onnx"))
    assert load_model("none") is None


@pytest.mark.skipif(not HAS_INFERENCE, reason="dptpu.models.inference is not in this build")
def test_missing_model_file_is_refused_at_start_naming_the_file(harness, tmp_path):
    with pytest.raises(ValueError, match=r"absent\.onnx: model file not found"):
        harness.start(UnwrapNode, model=str(tmp_path / "absent.onnx"))
    with pytest.raises(ValueError, match="model refines a two-frequency method"):
        harness.start(UnwrapNode, method="heterodyne", model=str(tmp_path / "absent.onnx"))


@pytest.fixture(scope="module")
def shifted_model(tmp_path_factory):
    """A real ONNX model with the DP-TPU interface whose output is ``coarse_order + 1``, so the test can see the
    network's order in the result (built with onnx.helper: no torch, a second to make and load)."""
    return _offset_model(tmp_path_factory.mktemp("model") / "shifted.onnx", 1.0)


@pytest.fixture(scope="module")
def prior_model(tmp_path_factory):
    """As :func:`shifted_model`, its output the coarse order itself (right on the plane: the prior is)."""
    return _offset_model(tmp_path_factory.mktemp("model") / "prior.onnx", 0.0)


def _offset_model(path, offset: float):
    if not HAS_INFERENCE:
        pytest.skip("dptpu.models.inference is not in this build")
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    from dptpu.models.inference import MODEL_FORMAT

    def image(name):
        return helper.make_tensor_value_info(name, TensorProto.FLOAT, ["B", 1, "H", "W"])

    graph = helper.make_graph(
        [helper.make_node("Add", ["coarse_order", "one"], ["fringe_order"])], "shifted_order",
        [image("wrapped_high"), image("wrapped_low"), image("coarse_order"),
         helper.make_tensor_value_info("frequency_high", TensorProto.FLOAT, ["B"])],
        [image("fringe_order")], initializer=[helper.make_tensor("one", TensorProto.FLOAT, [], [offset])])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
    helper.set_model_props(model, {"dptpu_format": MODEL_FORMAT, "kind": "dptpu", "config": "{}", "training": "{}"})
    onnx.save(model, str(path))
    return path


def test_model_refines_the_classical_order_with_the_network(harness, scene, shifted_model):
    # min_confidence 0: the low frequency rejects the shifted order as a whole (dptpu.fpp.region_consistency)
    node, source, absolute, status = start(harness, method="mf", model=str(shifted_model), min_confidence=0.0)
    maps = phase_maps(scene, (16.0, 1.0), sequence_id=9)
    source.publish(maps)
    (result,) = harness.wait(absolute, 1)
    assert result.method == "dptpu"
    classical = unwrap_mf(maps.phases[0], maps.phases[1], 16.0, 1.0).fringe_order  # right at every pixel
    on_projector = classical + 1 < 16  # an order off the projector is invalid
    assert np.array_equal(result.valid, on_projector)
    assert np.all(result.reliability == 0.0)  # every pixel one order off: no confidence anywhere
    assert np.array_equal(result.fringe_order[on_projector], classical[on_projector] + 1)
    psi_h = maps.phases[0].astype(np.float64)
    assert np.allclose(result.absolute_phase[on_projector], (psi_h + 2 * np.pi * (classical + 1))[on_projector],
                       atol=1e-4)


def test_consensus_restores_the_classical_orders_a_wrong_network_changed(harness, scene, shifted_model):
    """The shifted model moves every order by +1; on the plane every classical order agrees with its neighbours,
    so the consensus (step 1, docs/model-eval.md) keeps the classical order at every pixel."""
    _node, source, absolute, _status = start(harness, method="mf", model=str(shifted_model), consensus=True)
    maps = phase_maps(scene, (16.0, 1.0), sequence_id=11)
    source.publish(maps)
    (result,) = harness.wait(absolute, 1)
    classical = unwrap_mf(maps.phases[0], maps.phases[1], 16.0, 1.0)
    assert result.method == "dptpu"
    assert np.array_equal(result.valid, classical.valid)
    assert np.array_equal(result.fringe_order[result.valid], classical.fringe_order[result.valid])


def test_nt_reaches_the_network_through_its_band_prior(harness, scene, shifted_model):
    """NT at 60 / 10.9 is nearly degenerate (k_l and k_l + 2 predict high phases 0.009 periods apart): with
    0.03 rad of noise the lookup gets most pixels wrong, the band prior (dptpu.models.nt_prior) gets them right,
    and the node gives the network that prior's order (the shifted model adds 1 to it)."""
    from dptpu.fpp.tpu import unwrap_nt

    # min_confidence 0: the low frequency rejects the shifted order (dptpu.fpp.region_consistency)
    _node, source, absolute, _status = start(harness, method="nt", model=str(shifted_model), min_confidence=0.0)
    rng = np.random.default_rng(3)
    phases = np.stack([np.mod(scene.absolute_phase(f) + rng.normal(0, 0.03, scene.lit.shape), 2 * np.pi)
                       for f in (60.0, 10.9)]).astype(np.float32)
    maps = phase_maps(scene, (60.0, 10.9), sequence_id=13)
    maps.phases = phases
    source.publish(maps)
    (result,) = harness.wait(absolute, 1)
    truth = np.floor(scene.absolute_phase(60.0) / (2 * np.pi)).astype(np.int32)
    lookup = unwrap_nt(phases[0], phases[1], 60.0, 10.9, 912.0).fringe_order
    assert np.mean(lookup == truth) < 0.5  # measured 24.9 %
    shifted = result.fringe_order[result.valid] - 1
    assert result.valid.mean() > 0.9 and np.mean(shifted == truth[result.valid]) > 0.98  # measured 99.4 / 99.6 %


def test_consensus_without_a_model_is_refused_at_start(harness):
    with pytest.raises(ValueError, match=r"consensus post-processes the network's fringe order; set model"):
        harness.start(UnwrapNode, consensus=True)


def test_nt_without_the_projector_size_is_reported(harness, scene):
    node, source, absolute, status = start(harness, method="nt")
    maps = phase_maps(scene, (16.0, 15.0), sequence_id=4)
    maps.projector_width = maps.projector_height = 0
    source.publish(maps)
    (failed,) = harness.wait(status, 1)
    assert failed.reason == ("cannot unwrap scan 4 (nt): nt needs the projector extent; the PhaseMaps has "
                             "projector size 0 (unknown)")


def test_pixels_below_min_confidence_are_dropped_and_counted(harness, scene):
    node, source, absolute, status = start(harness, method="mf", min_confidence=0.9)
    maps = phase_maps(scene, (64.0, 1.0), sequence_id=21)  # ratio 64: noise of q ~0.05, margins spread over [0.7, 1]
    source.publish(maps)
    (result,) = harness.wait(absolute, 1)
    classical = unwrap_mf_float32(maps.phases[0], maps.phases[1], 64.0, 1.0)  # as the node unwraps mf
    with np.errstate(invalid="ignore"):
        valid = classical.valid & (classical.absolute_phase >= 0) & (classical.absolute_phase < 2 * np.pi * 64.0)
    low = int(np.count_nonzero(valid & (classical.reliability < 0.9)))
    assert low > 0 and node.pixels_low_confidence == low
    assert np.array_equal(result.valid, valid & (classical.reliability >= 0.9))
    (ok,) = harness.wait(status, 1)
    assert ok.level == ScanStatus.OK and f"{low} pixels below min_confidence 0.9 dropped" in ok.reason


def test_the_networks_confidence_reaches_the_reliability_field(harness, scene, prior_model):
    # the model's output is exactly an integer, its prior's order: its own margin is 1, so the published confidence
    # is the two frequencies' agreement (dptpu.fpp.frequency_consistency), the smaller one
    _node, source, absolute, _status = start(harness, method="mf", model=str(prior_model))
    maps = phase_maps(scene, (16.0, 1.0), sequence_id=23)
    source.publish(maps)
    (result,) = harness.wait(absolute, 1)
    consistency = frequency_consistency(result.absolute_phase, maps.phases[1], 16.0, 1.0, result.valid)
    assert result.valid.any() and np.allclose(result.reliability[result.valid], consistency[result.valid], atol=0.02)
    assert np.all(result.reliability[~result.valid] == 0.0)


@pytest.mark.skipif(not HAS_INFERENCE, reason="dptpu.models.inference is not in this build")
def test_auto_model_serves_a_scan_within_the_models_fringes_and_says_why_not_beyond(harness, scene):
    from dptpu.models.inference import shipped_model_path
    from dptpu.models.refine import fringe_density

    if shipped_model_path() is None:
        pytest.skip("no shipped model")
    node, source, absolute, status = start(harness, method="mf", model="auto")
    maps = phase_maps(scene, (16.0, 1.0), sequence_id=31)
    density = fringe_density(maps.phases[0])
    assert density < 0.25
    dense = 16.0 * 0.3 / density  # 0.3 periods per camera pixel
    source.publish(maps)
    source.publish(phase_maps(scene, (dense, 1.0), sequence_id=32))
    first, second = harness.wait(absolute, 2)
    assert (first.method, second.method) == ("dptpu", "mf")
    _, skipped = harness.wait(status, 2)
    assert "no model: fringes of 0.30 periods per camera pixel" in skipped.reason and node.scans_without_model == 1
