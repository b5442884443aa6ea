"""The torch network of an exported ONNX model: its weights copied back from the ONNX initializers.

Fine-tuning needs the trained weights in torch, and a shipped model may exist only as its ``.onnx`` file
(:mod:`dptpu.models.export`). Most initializers keep their ``state_dict`` names (``stem.0.weight``); the exporter
constant-folds the channel norms' ``weight[None, :, None, None]`` into anonymous ``(1, C, 1, 1)`` initializers
(``onnx::Mul_2727``), and a parameter the forward pass multiplies by a constant into its product. Their names
are recovered by exporting a network of the same architecture whose unnamed parameters hold marker values (each a
distinct ramp) and reading which anonymous initializer holds which marker, and times what.
The result is checked end to end: the torch network must reproduce onnxruntime's output on a test input
(:data:`MAX_ABS_DIFFERENCE`), else ValueError.
"""
from __future__ import annotations

import functools
import json
import tempfile
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .factory import build_model

__all__ = ["load_onnx_model", "MAX_ABS_DIFFERENCE"]

#: Largest accepted difference (fringe orders) between the recovered torch network and onnxruntime.
MAX_ABS_DIFFERENCE = 1e-3


def _initializers(proto) -> dict:
    from onnx import numpy_helper

    return {init.name: numpy_helper.to_array(init) for init in proto.graph.initializer}


def _metadata(proto, path: Path) -> tuple[str, dict, dict]:
    metadata = {p.key: p.value for p in proto.metadata_props}
    if metadata.get("dptpu_format") != "dptpu-model/1":
        raise ValueError(f"{path}: ONNX model without dptpu metadata (dptpu_format dptpu-model/1)")
    return metadata.get("kind", "dptpu"), json.loads(metadata.get("config", "{}")), \
        json.loads(metadata.get("training", "{}"))


def _folded_names(kind: str, config: dict, keys: list[str]) -> list:
    """``[(state_dict key, flat indices, scale) or None]`` for the anonymous initializers of an export, in graph
    order (:func:`_folded_names_cached`)."""
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
    from .export import export_onnx
    import onnx

    model = build_model(kind, json.loads(config_json))
    state = model.state_dict()
    markers, owner, offset = {}, {}, 0
    with torch.no_grad():
        for key in keys:
            size = state[key].numel()
            marker = offset + np.arange(size, dtype=np.float64) + 0.5
            state[key].copy_(torch.from_numpy(marker.astype(np.float32)).reshape(state[key].shape))
            markers[key] = (offset, marker)
            offset += size
    with tempfile.TemporaryDirectory() as folder:
        path = export_onnx(model, Path(folder) / "markers.onnx")
        found = _initializers(onnx.load(str(path)))
    starts = np.array([markers[k][0] for k in keys])
    matches = []
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
        matches.append(match)
    return tuple(matches)


def _check_against_onnxruntime(model: nn.Module, path: Path) -> float:
    from .inference import FringeOrderModel

    generator = np.random.default_rng(0)
    high, low = (generator.uniform(0, 2 * np.pi, (1, 48, 80)).astype(np.float32) for _ in range(2))
    coarse = generator.integers(0, 40, (1, 48, 80)).astype(np.float32)
    frequency = np.array([48.0], np.float32)
    reference = FringeOrderModel.load(path, threads=1).predict(high, low, coarse, frequency)
    with torch.no_grad():
        ours = model(*(torch.from_numpy(a[:, None]) for a in (high, low, coarse)), torch.from_numpy(frequency))
    return float(np.max(np.abs(ours.numpy()[:, 0] - reference)))


def load_onnx_model(path) -> tuple[nn.Module, dict]:
    """The torch network (eval mode) of an exported ONNX model, and the model's ``training`` metadata.

    Parameters
    ----------
    path : path
        ``.onnx`` file written by :func:`dptpu.models.export.export_onnx`.

    Returns
    -------
    (nn.Module, dict)
        The network with every parameter copied from the ONNX initializers (checked against onnxruntime to
        :data:`MAX_ABS_DIFFERENCE`), and the ``training`` metadata (``kind`` and ``config`` added).

    Raises
    ------
    ValueError
        Not a dptpu ONNX model, a parameter that cannot be found in it, or a network that does not reproduce
        onnxruntime's output (then pass the training checkpoint instead).
    """
    import onnx

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such ONNX model")
    try:
        proto = onnx.load(str(path))
    except Exception as exc:  # a truncated or foreign file
        raise ValueError(f"{path}: not a readable ONNX model ({type(exc).__name__}: {exc})") from None
    kind, config, training = _metadata(proto, path)
    model = build_model(kind, config or None)
    state = model.state_dict()
    found = _initializers(proto)
    missing = [key for key in state if key not in found]
    anonymous = [name for name in found if name not in state]
    matches = _folded_names(kind, config or None, missing) if missing else []
    by_key = {key: np.asarray(found[key], np.float64).ravel() for key in state if key in found}
    filled = {key: np.zeros(state[key].numel(), bool) for key in missing}
    if len(matches) == len(anonymous):
        for name, match in zip(anonymous, matches):
            if match is None:
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
