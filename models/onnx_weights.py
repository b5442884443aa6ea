"""The torch network of an exported ONNX model: its weights copied back from the ONNX initializers.

Fine-tuning needs the trained weights in torch, and a shipped model may exist only as its ``.onnx`` file
(:mod:`dptpu.models.export`). A fast graph (``graph`` metadata ``dptpu-fast/1``) carries every parameter under its
``state_dict`` name in the model's ``training_info``. In a traced graph most initializers keep their ``state_dict``
names (``stem.0.weight``); the exporter
constant-folds others into anonymous initializers (``onnx::Mul_2727``): a channel norm's
``weight[None, :, None, None]``, a slice ``weight[:, :1]``, a parameter times a constant gain; and it merges equal
constants into one, read through ``Identity`` nodes. They are recovered by exporting a network of the same
architecture whose parameters hold marker values (distinct half-integers) and reading, at each use of an
initializer by a node (the nodes of two exports of one architecture are the same, their anonymous names are not),
which parameter elements it holds and times what. The result is checked end to end: the torch network must
reproduce onnxruntime's output on a test input (:data:`MAX_ABS_DIFFERENCE`), else ValueError.
"""
from __future__ import annotations

import functools
import json
import tempfile
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .export import export_onnx
from .factory import FringeOrderNet, build_model
from .inference import FringeOrderModel

__all__ = ["MAX_ABS_DIFFERENCE", "convert_onnx", "load_onnx_model"]

#: Largest accepted difference (fringe orders) between the recovered torch network and onnxruntime.
MAX_ABS_DIFFERENCE = 1e-3


def _initializers(proto) -> dict:
    """The graph's initializers and those of its ``training_info`` (where a fast graph keeps the raw parameters)."""
    from onnx import numpy_helper  # onnx: an optional dependency (training)

    found = {init.name: numpy_helper.to_array(init) for init in proto.graph.initializer}
    for info in proto.training_info:
        found.update({init.name: numpy_helper.to_array(init) for init in info.initialization.initializer})
    return found


def _metadata(proto, path: Path) -> tuple[str, dict, dict]:
    metadata = {p.key: p.value for p in proto.metadata_props}
    if metadata.get("dptpu_format") != "dptpu-model/1":
        raise ValueError(f"{path}: ONNX model without dptpu metadata (dptpu_format dptpu-model/1)")
    return metadata.get("kind", "dptpu"), json.loads(metadata.get("config", "{}")), \
        json.loads(metadata.get("training", "{}"))


def _anonymous_uses(proto, state) -> list:
    """``[((node index, op type, input slot), initializer name)]`` of every use of an initializer that is not a
    ``state_dict`` entry (of every initializer when ``state`` is None), in graph order. The nodes of two exports of one
    architecture are the same; their anonymous names are not (they count what the exporter traced before), and equal
    constants (e.g. the norms of an untrained network, all ones) are merged into one initializer read through
    ``Identity`` nodes, which are resolved and not counted."""
    initializers = {init.name for init in proto.graph.initializer}
    alias = {node.output[0]: node.input[0] for node in proto.graph.node
             if node.op_type == "Identity" and node.input and node.input[0] in initializers}
    anonymous = initializers if state is None else {name for name in initializers if name not in state}
    uses, index = [], 0
    for node in proto.graph.node:
        if node.op_type == "Identity" and node.output and node.output[0] in alias:
            continue
        for slot, name in enumerate(node.input):
            name = alias.get(name, name)
            if name in anonymous:
                uses.append(((index, node.op_type, slot), name))
        index += 1
    return uses


def _folded_names(kind: str, config: dict | None, keys: list[str]) -> list:
    """``[(use, (state_dict key, flat indices, scale) or None)]`` for the uses of anonymous initializers of an
    export (:func:`_anonymous_uses`, :func:`_folded_names_cached`)."""
    return list(_folded_names_cached(kind, json.dumps(config, sort_keys=True), tuple(keys)))


@functools.lru_cache(maxsize=8)
def _folded_names_cached(kind: str, config_json: str, keys: tuple) -> tuple:
    """Export a network whose parameters ``keys`` hold markers and read what each anonymous initializer holds.

    Element ``i`` of the ``j``-th parameter holds ``offset_j + i + 0.5`` (distinct half-integers, exact in float32).
    An anonymous initializer is either a copy of elements of one parameter (a reshape, or a slice such as
    ``weight[:, :1]``: every value is a marker, ``scale`` 1) or the whole parameter times a constant (a gain the
    forward pass multiplies by: ``scale = value / marker`` is the same for every element; a half-integer times a
    scale is no marker). The anonymous names (``onnx::Mul_N``) depend on what the exporter traced before in the
    process, so they are matched by their position among the anonymous initializers, which the architecture fixes.
    """
    import onnx  # an optional dependency (training)

    model = build_model(kind, json.loads(config_json))
    state = model.state_dict()
    markers, offset = {}, 0
    with torch.no_grad():
        for key in keys:
            size = state[key].numel()
            marker = offset + np.arange(size, dtype=np.float64) + 0.5
            state[key].copy_(torch.from_numpy(marker.astype(np.float32)).reshape(state[key].shape))
            markers[key] = (offset, marker)
            offset += size
    with tempfile.TemporaryDirectory() as folder:
        path = export_onnx(model, Path(folder) / "markers.onnx", graph="torch")  # traced files need markers
        proto = onnx.load(str(path))
        found = _initializers(proto)
    starts = np.array([markers[k][0] for k in keys])
    matches = {}
    for name, values in found.items():
        if name in state:
            continue
        flat = values.astype(np.float64).ravel()
        match = None
        whole = np.floor(flat)
        if flat.size and np.all(flat - whole == 0.5) and np.all((whole >= 0) & (whole < offset)):
            which = np.searchsorted(starts, whole, side="right") - 1  # parameter of each element
            if np.all(which == which[0]):
                key = keys[int(which[0])]
                match = (key, (whole - markers[key][0]).astype(np.int64), 1.0)
        if match is None:
            for key, (_, marker) in markers.items():
                if flat.shape == marker.shape:
                    ratio = flat / marker
                    if ratio[0] != 0 and np.max(np.abs(ratio / ratio[0] - 1.0)) < 1e-6:
                        match = (key, np.arange(flat.size), float(ratio[0]))
        matches[name] = match
    return tuple((use, matches[name]) for use, name in _anonymous_uses(proto, state))


def _check_against_onnxruntime(model: nn.Module, path: Path) -> float:
    generator = np.random.default_rng(0)
    high, low = (generator.uniform(0, 2 * np.pi, (1, 48, 80)).astype(np.float32) for _ in range(2))
    coarse = generator.integers(0, 40, (1, 48, 80)).astype(np.float32)
    frequency = np.array([48.0], np.float32)
    reference = FringeOrderModel.load(path, threads=1).predict(high, low, coarse, frequency)
    with torch.no_grad():
        ours = model(*(torch.from_numpy(a[:, None]) for a in (high, low, coarse)), torch.from_numpy(frequency))
    return float(np.max(np.abs(ours.numpy()[:, 0] - reference)))


def load_onnx_model(path) -> tuple[FringeOrderNet, dict]:
    """The torch network (eval mode) of an exported ONNX model, and the model's ``training`` metadata.

    Parameters
    ----------
    path : path
        ``.onnx`` file written by :func:`dptpu.models.export.export_onnx`.

    Returns
    -------
    (DPTPUNet or UNetBaseline, dict)
        The network with every parameter copied from the ONNX initializers (checked against onnxruntime to
        :data:`MAX_ABS_DIFFERENCE`), and the ``training`` metadata (``kind`` and ``config`` added).

    Raises
    ------
    ValueError
        Not a dptpu ONNX model, a parameter that cannot be found in it, or a network that does not reproduce
        onnxruntime's output (then pass the training checkpoint instead).
    """
    import onnx  # an optional dependency (training)

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such ONNX model")
    try:
        proto = onnx.load(str(path))
    except Exception as exc:  # noqa: BLE001 -- a truncated or foreign file raises many exception types
        raise ValueError(f"{path}: not a readable ONNX model ({type(exc).__name__}: {exc})") from None
    kind, config, training = _metadata(proto, path)
    model = build_model(kind, config or None)
    state = model.state_dict()
    found = _initializers(proto)
    missing = [key for key in state if key not in found]
    uses = dict(_anonymous_uses(proto, None))  # a constant may be merged with a named one (zeros, ones)
    matches = _folded_names(kind, config or None, missing) if missing else []
    by_key = {key: np.asarray(found[key], np.float64).ravel() for key in state if key in found}
    filled = {key: np.zeros(state[key].numel(), bool) for key in missing}
    for use, match in matches:
        name = uses.get(use)
        if match is None or name is None or found[name].size != len(match[1]):
            continue
        key, indices, scale = match
        values = by_key.setdefault(key, np.zeros(state[key].numel()))
        values[indices] = np.asarray(found[name], np.float64).ravel() / scale
        filled[key][indices] = True
    unresolved = [key for key in state if key not in by_key or (key in filled and not filled[key].all())]
    if unresolved:
        raise ValueError(f"{path}: parameters {unresolved[:4]}{' ...' if len(unresolved) > 4 else ''} not found "
                         "among the ONNX initializers (an exporter other than this torch's?); pass the training "
                         "checkpoint instead")
    with torch.no_grad():
        for key, tensor in state.items():
            values = np.asarray(by_key[key], dtype=np.float32)
            if values.size != tensor.numel():
                raise ValueError(f"{path}: initializer of {key} has {values.size} values; the network's "
                                 f"{tuple(tensor.shape)} needs {tensor.numel()}")
            tensor.copy_(torch.from_numpy(values.copy()).reshape(tensor.shape))
    model.eval()
    difference = _check_against_onnxruntime(model, path)
    if not difference <= MAX_ABS_DIFFERENCE:
        raise ValueError(f"{path}: the weights read back from the ONNX initializers give outputs {difference:.3g} "
                         f"orders away from onnxruntime's (limit {MAX_ABS_DIFFERENCE:g}); pass the training "
                         "checkpoint instead")
    return model, {**training, "kind": kind, "config": config, "max_abs_difference": difference}


def convert_onnx(path, out, *, graph: str = "fast") -> Path:
    """Write the model of the exported file ``path`` again with ``graph`` (e.g. a traced model as a fast one).

    The weights are read back with :func:`load_onnx_model` (checked against onnxruntime), the metadata's
    ``training`` is kept; returns ``out``.
    """
    model, training = load_onnx_model(path)
    training = {k: v for k, v in training.items() if k not in ("kind", "config", "max_abs_difference")}
    return export_onnx(model, out, training=training, graph=graph)
