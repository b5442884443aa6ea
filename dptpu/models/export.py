"""Export a trained network to one ONNX file with dynamic batch, height and width.

The graph takes the four physical inputs and returns the continuous fringe order; the input scaling and
the padding to a multiple of 32 (and the crop back) are inside the graph, so any image size runs.

=============== ================= ==========================================================
input           shape             meaning
=============== ================= ==========================================================
wrapped_high    (B, 1, H, W) f32  wrapped phase of the high frequency, radians in [0, 2pi)
wrapped_low     (B, 1, H, W) f32  wrapped phase of the low frequency, radians in [0, 2pi)
coarse_order    (B, 1, H, W) f32  the classical method's fringe order (DP-TPU only)
frequency_high  (B,) f32          periods across the projector (DP-TPU only)
fringe_order    (B, 1, H, W) f32  output: continuous fringe order of the high frequency
=============== ================= ==========================================================

The U-Net baseline ignores ``coarse_order`` and ``frequency_high``, so its graph has only the two phases
as inputs (:mod:`dptpu.models.inference` feeds what the graph declares).

ONNX metadata (``metadata_props``): ``dptpu_format`` (``dptpu-model/1``), ``kind``, ``config`` (JSON),
``training`` (JSON: data, seed, epochs, ...). Opset 18, exported with the TorchScript-based exporter
(``dynamo=False``), which handles the data-dependent padding in seconds.
"""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import torch
from torch import nn

from .factory import build_model, model_config

__all__ = ["MODEL_FORMAT", "INPUT_NAMES", "OUTPUT_NAME", "OPSET", "export_onnx", "load_checkpoint_model"]

MODEL_FORMAT = "dptpu-model/1"
INPUT_NAMES = ("wrapped_high", "wrapped_low", "coarse_order", "frequency_high")
OUTPUT_NAME = "fringe_order"
OPSET = 18


def _example_inputs(height: int = 64, width: int = 96) -> tuple[torch.Tensor, ...]:
    generator = torch.Generator().manual_seed(0)
    phase = lambda: torch.rand(2, 1, height, width, generator=generator) * 2 * torch.pi  # noqa: E731
    return phase(), phase(), torch.randint(0, 60, (2, 1, height, width), generator=generator).float(), \
        torch.tensor([64.0, 48.0])


def export_onnx(model: nn.Module, out, *, training: dict | None = None) -> Path:
    """Write ``model`` (eval mode) to the ONNX file ``out`` and return its path.

    Parameters
    ----------
    model : DPTPUNet or UNetBaseline
    out : path
        Output ``.onnx`` file; its folder must exist. Written to a temporary name, then renamed.
    training : dict, optional
        Facts about the training run for the metadata (JSON-serializable).
    """
    import onnx

    out = Path(out)
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out.parent}: output folder does not exist")
    was_training = model.training
    model.eval()
    dynamic = {name: {0: "batch", 2: "height", 3: "width"} for name in INPUT_NAMES[:3]}
    dynamic["frequency_high"] = {0: "batch"}
    dynamic[OUTPUT_NAME] = {0: "batch", 2: "height", 3: "width"}
    tmp = out.with_name(out.name + ".tmp")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(model, _example_inputs(), str(tmp), input_names=list(INPUT_NAMES),
                          output_names=[OUTPUT_NAME], dynamic_axes=dynamic, opset_version=OPSET, dynamo=False)
    model.train(was_training)
    proto = onnx.load(str(tmp))
    metadata = {"dptpu_format": MODEL_FORMAT, "kind": model.kind, "config": json.dumps(model_config(model)),
                "training": json.dumps(training or {})}
    del proto.metadata_props[:]
    for key, value in metadata.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(proto, str(tmp))
    os.replace(tmp, out)
    return out


def load_checkpoint_model(path) -> tuple[nn.Module, dict]:
    """The network saved in a training checkpoint (eval mode) and the checkpoint dict."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint")
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # a truncated or foreign file
        raise ValueError(f"{path}: not a dptpu training checkpoint ({type(exc).__name__}: {exc})") from None
    if not isinstance(checkpoint, dict) or checkpoint.get("format") != "dptpu-checkpoint/1":
        raise ValueError(f"{path}: not a dptpu training checkpoint (format dptpu-checkpoint/1)")
    model = build_model(checkpoint["kind"], checkpoint["config"])
    model.load_state_dict(checkpoint["model"])
    return model.eval(), checkpoint
