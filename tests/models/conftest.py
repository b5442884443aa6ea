"""Fixtures of the DP-TPU network tests: a tiny toy dataset, a tiny architecture, a tiny exported model.

Everything is small (64x64 samples, 8-channel stages) so the whole area runs in well under a minute on
two CPU cores.
"""
from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="the DP-TPU tests need torch (the 'train' extra)")
# One intra-op thread: tiny models gain nothing from more, and on a busy 2-core machine OpenMP threads that
# spin-wait for each other make a 0.1 s forward pass take seconds.
torch.set_num_threads(1)

#: A tiny DP-TPU architecture (a few thousand parameters).
TINY_DPTPU = {"widths": [8, 8, 8, 8], "depths": [1, 1, 1, 1], "heads": [1, 1, 1, 2], "decoder_width": 8}
TINY_UNET = {"widths": [4, 4, 8, 8, 8]}


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """8 toy samples of 64x64: MF and NT at f_h 32 and 80, two scenes each, 1 sigma noise."""
    from dptpu.models.toy_dataset import write_toy_dataset

    return write_toy_dataset(tmp_path_factory.mktemp("toy") / "data", frequencies=(32, 80), methods=("mf", "nt"),
                             scenes=2, shape=(64, 64), seed=3)


def randomize_head(model, seed=0):
    """Give the zero-initialized last layers of DP-TPU (correction and gate) random weights, so its output
    differs from its input (the gate is scaled by GATE_GAIN, so its weights get a smaller spread)."""
    generator = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for layer, spread in ((model.head_correction, 0.5), (model.head_gate, 0.05)):
            for p in layer.parameters():
                p.copy_(torch.randn(p.shape, generator=generator) * spread)
    return model


@pytest.fixture(scope="session")
def tiny_onnx(tmp_path_factory):
    """A tiny DP-TPU with a random head exported to ONNX: (path, torch model)."""
    from dptpu.models.export import export_onnx
    from dptpu.models.factory import build_model

    torch.manual_seed(0)
    model = randomize_head(build_model("dptpu", TINY_DPTPU)).eval()
    path = export_onnx(model, tmp_path_factory.mktemp("onnx") / "tiny.onnx", training={"note": "test"})
    return path, model


def phase_inputs(shape, seed=0, batch=None):
    """Random wrapped phases (radians), coarse orders and frequencies as float32 numpy arrays."""
    rng = np.random.default_rng(seed)
    full = shape if batch is None else (batch, *shape)
    high = rng.uniform(0, 2 * np.pi, full).astype(np.float32)
    low = rng.uniform(0, 2 * np.pi, full).astype(np.float32)
    coarse = rng.integers(0, 64, full).astype(np.float32)
    frequency = np.float32(64.0) if batch is None else rng.choice([32.0, 64.0, 80.0], batch).astype(np.float32)
    return high, low, coarse, frequency
