"""ONNX export and onnxruntime inference: parity with torch, any size, no torch at inference, bad files."""
import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from dptpu.models.inference import FringeOrderModel, ModelLoadError

from .conftest import phase_inputs


@pytest.mark.parametrize("shape", [(45, 61), (96, 128)])
def test_onnxruntime_matches_torch_within_a_thousandth_of_an_order(tiny_onnx, shape):
    path, model = tiny_onnx
    high, low, coarse, frequency = phase_inputs(shape, seed=1, batch=3)
    with torch.no_grad():
        expected = model(*(torch.from_numpy(a)[:, None] for a in (high, low, coarse)),
                         torch.from_numpy(frequency))[:, 0].numpy()
    got = FringeOrderModel.load(path).predict(high, low, coarse, frequency)
    assert got.shape == (3, *shape)
    assert np.abs(got - expected).max() < 1e-3
    assert np.abs(expected - coarse).max() > 0.1  # the random head does change the order


def test_metadata_describes_the_model(tiny_onnx):
    loaded = FringeOrderModel.load(tiny_onnx[0])
    assert loaded.kind == "dptpu"
    assert loaded.config["widths"] == [8, 8, 8, 8]
    assert loaded.training == {"note": "test"}
    assert loaded.input_names == ("wrapped_high", "wrapped_low", "coarse_order", "frequency_high")


def test_refine_rounds_valid_pixels_and_keeps_the_classical_order_elsewhere(tiny_onnx):
    loaded = FringeOrderModel.load(tiny_onnx[0])
    high, low, coarse, _ = phase_inputs((37, 29), seed=2)
    valid = np.ones(high.shape, bool)
    valid[:10] = False
    high = high.astype(np.float64)
    high[0, 0] = np.nan  # an invalid pixel may be NaN
    order = loaded.refine(high, low, coarse, 64.0, valid=valid)
    assert order.dtype == np.int32 and order.shape == (37, 29)
    assert np.array_equal(order[:10, 1:], coarse[:10, 1:].astype(np.int32))
    assert order[0, 0] == int(coarse[0, 0])  # NaN phase: the classical order stays
    continuous = loaded.predict(np.where(valid, high, 0), np.where(valid, low, 0), np.where(valid, coarse, 0), 64.0)
    assert np.array_equal(order[10:], np.rint(continuous[10:]).astype(np.int32))


def test_inference_never_imports_torch(tiny_onnx):
    code = (
        "import sys, numpy as np\n"
        "from dptpu.models.inference import FringeOrderModel\n"
        f"model = FringeOrderModel.load({str(tiny_onnx[0])!r})\n"
        "rng = np.random.default_rng(0)\n"
        "phase = rng.uniform(0, 6.28, (40, 50))\n"
        "order = model.refine(phase, phase, np.full((40, 50), 3.0), 32.0)\n"
        "print(order.shape, 'torch' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "(40, 50) False"


def test_missing_corrupt_and_foreign_files_raise_a_value_error_naming_the_file(tmp_path, tiny_onnx):
    with pytest.raises(ModelLoadError, match="nothere.onnx: model file not found"):
        FringeOrderModel.load(tmp_path / "nothere.onnx")
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(tiny_onnx[0].read_bytes()[:5000])
    with pytest.raises(ValueError, match="corrupt.onnx: not a loadable ONNX model"):
        FringeOrderModel.load(corrupt)
    import onnx

    foreign = onnx.load(str(tiny_onnx[0]))
    del foreign.metadata_props[:]
    onnx.save(foreign, str(tmp_path / "foreign.onnx"))
    with pytest.raises(ValueError, match="foreign.onnx: ONNX model without dptpu metadata"):
        FringeOrderModel.load(tmp_path / "foreign.onnx")


def test_unet_graph_takes_only_the_two_phases(tmp_path):
    from dptpu.models.export import export_onnx
    from dptpu.models.factory import build_model

    from .conftest import TINY_UNET

    torch.manual_seed(0)
    model = build_model("unet", TINY_UNET).eval()
    loaded = FringeOrderModel.load(export_onnx(model, tmp_path / "unet.onnx"))
    assert loaded.kind == "unet" and loaded.input_names == ("wrapped_high", "wrapped_low")
    high, low, coarse, frequency = phase_inputs((33, 40), seed=4, batch=2)
    with torch.no_grad():
        expected = model(*(torch.from_numpy(a)[:, None] for a in (high, low, coarse)),
                         torch.from_numpy(frequency))[:, 0].numpy()
    assert np.abs(loaded.predict(high, low, coarse, frequency) - expected).max() < 1e-3
    assert json.loads(json.dumps(loaded.config)) == {"widths": [4, 4, 8, 8, 8]}
