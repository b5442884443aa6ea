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
``training`` (JSON: data, seed, epochs, ...), and for the DP-TPU network ``graph`` (``dptpu-fast/1``). Opset 18.

Two ways to write the graph (``graph=``):

- ``"fast"`` (default for DP-TPU): :func:`dptpu.models.onnx_graph.build_dptpu_graph` writes the same function op
  by op from the weights (space-to-depth layout at full resolution, folded linear maps, static reshapes: fewer and
  cheaper kernels on onnxruntime than the traced graph, docs/benchmarks.md "Model: the fast graph"). The raw
  parameters ride along under their ``state_dict`` names in the model's ``training_info`` (ignored by
  onnxruntime), for :func:`dptpu.models.onnx_weights.load_onnx_model`.
- ``"torch"``: ``torch.onnx.export`` of the module with the TorchScript-based exporter (``dynamo=False``), which
  handles the data-dependent padding in seconds. The U-Net baseline always goes this way; models shipped before
  the fast graph have such a graph and still run.
"""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .factory import FringeOrderNet, build_model, model_config
from .onnx_graph import GRAPH_FORMAT, build_dptpu_graph

__all__ = [
    "GRAPHS",
    "INPUT_NAMES",
    "MODEL_FORMAT",
    "OPSET",
    "OUTPUT_NAME",
    "export_onnx",
    "load_checkpoint_model",
]

MODEL_FORMAT = "dptpu-model/1"
INPUT_NAMES = ("wrapped_high", "wrapped_low", "coarse_order", "frequency_high")
OUTPUT_NAME = "fringe_order"
OPSET = 18
#: Ways of writing the graph (module docstring); the first is the default for DP-TPU.
GRAPHS = ("fast", "torch")
#: Name of the ``training_info`` initialization graph that carries the raw parameters of a fast graph.
PARAMETERS_GRAPH = "dptpu_parameters"


def _example_inputs(height: int = 64, width: int = 96) -> tuple[torch.Tensor, ...]:
    generator = torch.Generator().manual_seed(0)

    def phase() -> torch.Tensor:
        return torch.rand(2, 1, height, width, generator=generator) * 2 * torch.pi

    return phase(), phase(), torch.randint(0, 60, (2, 1, height, width), generator=generator).float(), \
        torch.tensor([64.0, 48.0])


def export_onnx(model: FringeOrderNet, out, *, training: dict | None = None, graph: str = "fast") -> Path:
    """Write ``model`` (eval mode) to the ONNX file ``out`` and return its path.

    Parameters
    ----------
    model : DPTPUNet or UNetBaseline
    out : path
        Output ``.onnx`` file; its folder must exist. Written to a temporary name, then renamed.
    training : dict, optional
        Facts about the training run for the metadata (JSON-serializable).
    graph : {"fast", "torch"}
        How the DP-TPU graph is written (module docstring); the U-Net baseline is always traced.
    """
    import onnx  # an optional dependency (training)

    if graph not in GRAPHS:
        raise ValueError(f"export graph must be one of {', '.join(GRAPHS)}; got {graph!r}")
    out = Path(out)
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out.parent}: output folder does not exist")
    tmp = out.with_name(out.name + ".tmp")
    metadata = {"dptpu_format": MODEL_FORMAT, "kind": model.kind, "config": json.dumps(model_config(model)),
                "training": json.dumps(training or {})}
    if graph == "fast" and model.kind == "dptpu":
        proto = _fast_model(model)
        metadata["graph"] = GRAPH_FORMAT
    else:
        _trace(model, tmp)
        proto = onnx.load(str(tmp))
    del proto.metadata_props[:]
    for key, value in metadata.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(proto, str(tmp))
    os.replace(tmp, out)
    return out


def _trace(model: nn.Module, path: Path) -> None:
    """``torch.onnx.export`` of ``model`` in eval mode to ``path`` (the ``"torch"`` graph)."""
    was_training = model.training
    model.eval()
    dynamic = {name: {0: "batch", 2: "height", 3: "width"} for name in INPUT_NAMES[:3]}
    dynamic["frequency_high"] = {0: "batch"}
    dynamic[OUTPUT_NAME] = {0: "batch", 2: "height", 3: "width"}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            torch.onnx.export(model, _example_inputs(), str(path), input_names=list(INPUT_NAMES),
                              output_names=[OUTPUT_NAME], dynamic_axes=dynamic, opset_version=OPSET, dynamo=False)
    finally:
        model.train(was_training)


def _fast_model(model: nn.Module):
    """The ``"fast"`` ModelProto of a DPTPUNet: the graph of :func:`build_dptpu_graph` and, in ``training_info``,
    the raw parameters under their ``state_dict`` names."""
    from onnx import helper, numpy_helper  # an optional dependency (training)

    state = {key: value.detach().cpu().numpy().astype(np.float32) for key, value in model.state_dict().items()}
    proto = helper.make_model(build_dptpu_graph(state, model.config),
                              opset_imports=[helper.make_opsetid("", OPSET)], producer_name="dptpu")
    proto.ir_version = 8  # onnxruntime >= 1.14 reads it
    parameters = proto.training_info.add().initialization
    parameters.name = PARAMETERS_GRAPH
    parameters.initializer.extend(numpy_helper.from_array(value, name=key) for key, value in state.items())
    _check_fast_graph(model, proto)
    return proto


#: Largest accepted difference (fringe orders) between a fast graph and the module it was written from.
FAST_GRAPH_TOLERANCE = 1e-3


def _check_fast_graph(model: nn.Module, proto) -> None:
    """Raise ValueError unless onnxruntime on ``proto`` reproduces ``model`` on a random 37x45 input with invalid
    pixels to :data:`FAST_GRAPH_TOLERANCE` (a guard for edits of ``DPTPUNet.forward`` that
    :mod:`dptpu.models.onnx_graph` does not follow)."""
    import onnxruntime  # the check runs only at export; importers of export need not load it

    rng = np.random.default_rng(0)
    shape = (1, 1, 37, 45)
    invalid = rng.random(shape) < 0.1
    high, low = (np.where(invalid, 0, rng.uniform(0, 2 * np.pi, shape)).astype(np.float32) for _ in range(2))
    coarse = np.where(invalid, 0, rng.integers(0, 60, shape)).astype(np.float32)
    frequency = np.array([64.0], np.float32)
    options = onnxruntime.SessionOptions()
    options.log_severity_level = 3
    session = onnxruntime.InferenceSession(proto.SerializeToString(), options, providers=["CPUExecutionProvider"])
    got = session.run(None, {"wrapped_high": high, "wrapped_low": low, "coarse_order": coarse,
                             "frequency_high": frequency})[0]
    with torch.no_grad():
        expected = model(*(torch.from_numpy(a) for a in (high, low, coarse, frequency))).numpy()
    difference = float(np.max(np.abs(got - expected)))
    if not difference <= FAST_GRAPH_TOLERANCE:
        raise ValueError(f"the fast ONNX graph of this network is {difference:.3g} fringe orders away from "
                         f"DPTPUNet.forward (limit {FAST_GRAPH_TOLERANCE:g}): models/onnx_graph.py does not "
                         "follow models/network.py; export with graph='torch'")


def load_checkpoint_model(path) -> tuple[FringeOrderNet, dict]:
    """The network saved in a training checkpoint (eval mode) and the checkpoint dict."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint")
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 -- a truncated or foreign file raises many exception types
        raise ValueError(f"{path}: not a dptpu training checkpoint ({type(exc).__name__}: {exc})") from None
    if not isinstance(checkpoint, dict) or checkpoint.get("format") != "dptpu-checkpoint/1":
        raise ValueError(f"{path}: not a dptpu training checkpoint (format dptpu-checkpoint/1)")
    model = build_model(checkpoint["kind"], checkpoint["config"])
    model.load_state_dict(checkpoint["model"])
    return model.eval(), checkpoint
