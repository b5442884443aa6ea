"""The fast inference graph (dptpu.models.onnx_graph) computes what the torch module and its traced export compute.

Every parameter is randomized (channel-norm affines, biases, the zero-initialized heads), so each folding of a
linear map into a convolution is exercised; one config has two heads in stage 1 and one in the decoder, the other
the reverse (the one-head paths fold the projection into the values). Inputs have odd sizes (padding to 32) and
invalid pixels (the patch median's fill values and weights).
"""
import json

import numpy as np
import pytest
import torch

from dptpu.models.export import export_onnx
from dptpu.models.factory import build_model
from dptpu.models.inference import FringeOrderModel, shipped_model_path
from dptpu.models.onnx_graph import GRAPH_FORMAT
from dptpu.models.onnx_weights import convert_onnx, load_onnx_model

from .conftest import phase_inputs

CONFIGS = {
    "heads-2-1": {"widths": [8, 8, 8, 8], "depths": [1, 1, 1, 1], "heads": [2, 1, 1, 1], "decoder_width": 8},
    "heads-1-2": {"widths": [8, 8, 8, 16], "depths": [1, 1, 1, 1], "heads": [1, 1, 1, 2], "decoder_width": 8,
                  "reductions": [4, 2, 1], "recursions": 1, "decoder_pool": 1},
}


def _random_model(config: dict, seed: int):
    """A DP-TPU network with every parameter drawn at random (norm weights around 1, gate weights small)."""
    torch.manual_seed(seed)
    model = build_model("dptpu", config).eval()
    from dptpu.models.layers import ChannelNorm

    generator = torch.Generator().manual_seed(seed)

    def noise(p: torch.Tensor) -> torch.Tensor:
        return torch.randn(p.shape, generator=generator)

    with torch.no_grad():
        for name, module in model.named_modules():
            if isinstance(module, ChannelNorm):
                module.weight.copy_(1.0 + 0.3 * noise(module.weight))
                module.bias.copy_(0.3 * noise(module.bias))
            elif isinstance(module, torch.nn.Conv2d):
                scale = 0.02 if name == "head_gate" else 0.2
                module.weight.add_(scale * noise(module.weight))
                module.bias.add_(scale * noise(module.bias))
        for name, p in model.named_parameters():
            if name.endswith("query_dw"):
                p.add_(0.2 * noise(p))
    return model


def _inputs(shape, seed):
    """Batch of 2 random maps with an invalid block and scattered invalid pixels (0 in all three maps)."""
    high, low, coarse, frequency = phase_inputs(shape, seed=seed, batch=2)
    rng = np.random.default_rng(seed)
    invalid = rng.random(high.shape) < 0.08
    invalid[0, :9, :13] = True
    return [np.where(invalid, 0, a).astype(np.float32) for a in (high, low, coarse)] + [frequency]


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_fast_graph_matches_torch_and_the_traced_graph_within_a_thousandth_of_an_order(tmp_path, name):
    model = _random_model(CONFIGS[name], seed=3)
    fast = FringeOrderModel.load(export_onnx(model, tmp_path / "fast.onnx"), threads=1)
    traced = FringeOrderModel.load(export_onnx(model, tmp_path / "traced.onnx", graph="torch"), threads=1)
    high, low, coarse, frequency = _inputs((37, 71), seed=5)
    with torch.no_grad():
        expected = model(*(torch.from_numpy(a)[:, None] for a in (high, low, coarse)),
                         torch.from_numpy(frequency))[:, 0].numpy()
    got = fast.predict(high, low, coarse, frequency)
    assert got.shape == (2, 37, 71)
    assert np.abs(expected - coarse).max() > 0.5  # the random network does move the orders
    assert np.abs(got - expected).max() < 1e-3
    assert np.abs(got - traced.predict(high, low, coarse, frequency)).max() < 1e-3


def test_fast_file_keeps_every_parameter_by_name_and_a_traced_file_still_reads_back(tmp_path):
    model = _random_model(CONFIGS["heads-1-2"], seed=4)
    state = {k: v.numpy() for k, v in model.state_dict().items()}
    fast_path = export_onnx(model, tmp_path / "fast.onnx", training={"note": "fast"})
    loaded = FringeOrderModel.load(fast_path)
    assert loaded.training == {"note": "fast"} and loaded.config == json.loads(json.dumps(model.config.to_dict()))
    recovered, training = load_onnx_model(fast_path)
    assert training["note"] == "fast" and training["max_abs_difference"] < 1e-3
    for key, value in recovered.state_dict().items():
        assert np.array_equal(value.numpy(), state[key]), key  # stored verbatim
    traced_path = export_onnx(model, tmp_path / "traced.onnx", graph="torch")
    recovered, _ = load_onnx_model(traced_path)  # marker path of the traced exporter
    for key, value in recovered.state_dict().items():
        assert np.allclose(value.numpy(), state[key], rtol=1e-6, atol=1e-7), key
    converted = FringeOrderModel.load(convert_onnx(traced_path, tmp_path / "converted.onnx"))
    import onnx

    metadata = {p.key: p.value for p in onnx.load(str(tmp_path / "converted.onnx")).metadata_props}
    assert metadata["graph"] == GRAPH_FORMAT
    high, low, coarse, frequency = _inputs((33, 45), seed=6)
    assert np.abs(converted.predict(high, low, coarse, frequency)
                  - FringeOrderModel.load(traced_path).predict(high, low, coarse, frequency)).max() < 1e-3


def test_fast_export_refuses_a_network_its_graph_does_not_follow(tmp_path):
    model = _random_model(CONFIGS["heads-2-1"], seed=1)
    forward = model.forward
    model.forward = lambda *inputs: forward(*inputs) + 0.01  # an edit of DPTPUNet.forward the builder lacks
    with pytest.raises(ValueError, match=r"0.01 fringe orders away from DPTPUNet.forward .* export with graph='torch'"):
        export_onnx(model, tmp_path / "edited.onnx")
    assert not (tmp_path / "edited.onnx").exists()
    assert FringeOrderModel.load(export_onnx(model, tmp_path / "traced.onnx", graph="torch")).kind == "dptpu"


def test_export_rejects_an_unknown_graph(tmp_path):
    with pytest.raises(ValueError, match="export graph must be one of fast, torch; got 'onnxscript'"):
        export_onnx(_random_model(CONFIGS["heads-2-1"], seed=0), tmp_path / "x.onnx", graph="onnxscript")


def test_shipped_model_gives_the_same_orders_as_its_other_graph(tmp_path):
    """The shipped weights in the traced and the fast graph: same rounded orders on a toy scene of odd size."""
    from dptpu.models.toy_dataset import toy_sample

    path = shipped_model_path()
    if path is None:
        pytest.skip("the package has no shipped model (models/dptpu.onnx)")
    import onnx

    shipped_graph = {p.key: p.value for p in onnx.load(str(path)).metadata_props}.get("graph")
    other = convert_onnx(path, tmp_path / "other.onnx", graph="torch" if shipped_graph == GRAPH_FORMAT else "fast")
    sample = toy_sample("mf", 96.0, shape=(101, 139), noise_sigma=3.1386, scene_seed=7)
    valid = sample["valid"]
    inputs = [np.where(valid, sample[k], 0.0) for k in ("wrapped_high", "wrapped_low", "coarse_order")]
    first = FringeOrderModel.load(path, threads=1).predict(*inputs, 96.0)
    second = FringeOrderModel.load(other, threads=1).predict(*inputs, 96.0)
    assert np.abs(first - second)[valid].max() < 1e-3
    decided = valid & (np.abs(first - np.floor(first) - 0.5) > 1e-3)  # not within 1e-3 of a rounding tie
    assert decided[valid].mean() > 0.99
    assert np.array_equal(np.rint(first)[decided], np.rint(second)[decided])


def test_bench_model_times_the_fast_graph_beside_the_traced_one(tmp_path, capsys):
    from dptpu.cli.main import main

    model = _random_model(CONFIGS["heads-2-1"], seed=8)
    fast = export_onnx(model, tmp_path / "fast.onnx")
    traced = export_onnx(model, tmp_path / "traced.onnx", graph="torch")
    code = main(["bench", "model", "--model", str(fast), "--baseline", str(traced), "--size", "40x56", "--runs", "2",
                 "--warmup", "1", "--threads", "1", "--profile", "--profile-runs", "8", "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["graph"] == GRAPH_FORMAT and report["baseline_graph"] == "torch"
    assert report["size"] == [40, 56] and report["runs"] == 2
    assert report["baseline_max_abs_difference"] < 1e-3
    assert report["inference_ms_min"] <= report["inference_ms_p50"] <= report["inference_ms_p99"]
    assert 0.0 <= report["accuracy_model"] <= 1.0 and 0.5 < report["accuracy_classical"] <= 1.0
    # the fast graph runs fewer than half the kernels of the traced one (measured 701 against 1,369 at 480x640)
    assert 0 < report["profile_nodes"] < 0.6 * report["baseline_profile_nodes"]
    assert report["profile_sum_of_minima_ms"] == pytest.approx(sum(report["profile_by_op_ms"].values()), abs=0.05)
