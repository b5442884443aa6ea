"""The shipped model (dptpu/models/dptpu.onnx): it loads with onnxruntime and beats the classical order.

The held-out sample is an analytic step scene (dptpu.models.toy_dataset, a renderer the model never saw)
with a seed no training set used, at f_h = 96, outside the training frequencies S4 = {32, 48, 64, 80}.
"""
import numpy as np
import pytest

from dptpu.models.inference import FringeOrderModel, shipped_model_path
from dptpu.models.toy_dataset import toy_sample

pytestmark = pytest.mark.skipif(shipped_model_path() is None, reason="no shipped model dptpu/models/dptpu.onnx")


def _accuracy(order, sample):
    valid = sample["valid"]
    return float(np.mean(order[valid] == sample["label_order"][valid]))


@pytest.mark.parametrize("method", ["mf", "mw"])
def test_shipped_model_beats_the_classical_order_at_f96(method):
    model = FringeOrderModel.load(shipped_model_path(), threads=1)
    assert model.kind == "dptpu"
    classical, refined = [], []
    for seed in (900001, 900002):
        sample = toy_sample(method, 96.0, shape=(120, 160), noise_sigma=1.5693, scene_seed=seed)
        order = model.refine(sample["wrapped_high"], sample["wrapped_low"], sample["coarse_order"], 96.0,
                             valid=sample["valid"])
        classical.append(_accuracy(sample["coarse_order"].astype(np.int32), sample))
        refined.append(_accuracy(order, sample))
    assert np.mean(classical) < 0.95  # f_h = 96 at 1 sigma with 3 steps: the classical order fails often
    assert np.mean(refined) > np.mean(classical) + 0.02
