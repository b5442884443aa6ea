"""Fringe-order refinement with an exported DP-TPU (or U-Net) ONNX model, on onnxruntime alone.

Never imports torch (pinned by a test): the scanner nodes and ``dptpu unwrap`` load the shipped model
with onnxruntime only.

    model = FringeOrderModel.load("models/dptpu.onnx")
    order = model.refine(wrapped_high, wrapped_low, coarse_order, frequency_high, valid=valid)

Post-processing: the network's continuous fringe order is rounded to the nearest integer (the paper's
Fig. 9 pipeline); invalid pixels keep the classical order.
"""
from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

__all__ = ["MODEL_FORMAT", "SHIPPED_MODEL", "FringeOrderModel", "ModelLoadError", "shipped_model_path"]

MODEL_FORMAT = "dptpu-model/1"
#: The model trained and shipped with the package (``models/dptpu.onnx``).
SHIPPED_MODEL = Path(__file__).with_name("dptpu.onnx")
_TWO_PI = 2.0 * np.pi


class ModelLoadError(ValueError):
    """A model file is missing, corrupt or not a dptpu model (a ValueError: the CLI exits with 2)."""


def shipped_model_path() -> Path | None:
    """The shipped model file, or None when the package has none."""
    return SHIPPED_MODEL if SHIPPED_MODEL.is_file() else None


class _NodeArg(Protocol):
    """An input of an onnxruntime session (``onnxruntime.NodeArg``)."""

    @property
    def name(self) -> str: ...


class _Session(Protocol):
    """What the model uses of an ``onnxruntime.InferenceSession`` (onnxruntime ships no type information)."""

    def get_inputs(self) -> Sequence[_NodeArg]: ...

    def run(self, output_names: Sequence[str] | None, input_feed: Mapping[str, np.ndarray]) -> list[Any]: ...


@dataclass(frozen=True, eq=False)
class FringeOrderModel:
    """An onnxruntime session of an exported fringe-order network and its metadata.

    Attributes
    ----------
    path : Path
    kind : str
        ``"dptpu"`` or ``"unet"``.
    config : dict
        Architecture.
    training : dict
        What the exporter recorded about the training run.
    """

    path: Path
    kind: str
    config: dict
    training: dict
    _session: _Session

    @classmethod
    def load(cls, path, *, threads: int | None = None, spinning: bool = False) -> FringeOrderModel:
        """Open an exported model; ModelLoadError (a ValueError) naming the file if it cannot be used.

        Parameters
        ----------
        path : path
            ``.onnx`` file from :func:`dptpu.models.export.export_onnx`.
        threads : int, optional
            onnxruntime intra-op threads (default: onnxruntime's choice). Idle threads sleep instead of
            spinning (``session.intra_op.allow_spinning = 0``): on a machine shared with the scanner's
            other nodes, spinning threads steal the cores they wait for (docs/benchmarks.md, "Model: results").
        spinning : bool
            Let idle intra-op threads spin (``allow_spinning = 1``): only on otherwise idle cores, where a
            thread woken for every parallel op costs more than the op.
        """
        import onnxruntime as ort  # heavy: loaded with the first model, not with the module

        path = Path(path)
        if not path.is_file():
            raise ModelLoadError(f"{path}: model file not found (pass --model none for the classical result)")
        options = ort.SessionOptions()
        if threads is not None:
            options.intra_op_num_threads = int(threads)
        options.log_severity_level = 3
        options.add_session_config_entry("session.intra_op.allow_spinning", "1" if spinning else "0")
        try:
            session = ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # noqa: BLE001 -- onnxruntime raises its own exception types for corrupt files
            raise ModelLoadError(f"{path}: not a loadable ONNX model ({type(exc).__name__}: "
                                 f"{str(exc).splitlines()[0][:200]})") from None
        metadata = session.get_modelmeta().custom_metadata_map
        if metadata.get("dptpu_format") != MODEL_FORMAT:
            raise ModelLoadError(f"{path}: ONNX model without dptpu metadata (dptpu_format {MODEL_FORMAT}); "
                                 "export it with 'dptpu model export'")
        names = {i.name for i in session.get_inputs()}
        if not {"wrapped_high", "wrapped_low"} <= names:
            raise ModelLoadError(f"{path}: inputs {sorted(names)} lack wrapped_high / wrapped_low")
        return cls(path=path, kind=metadata.get("kind", "?"), config=json.loads(metadata.get("config", "{}")),
                   training=json.loads(metadata.get("training", "{}")), _session=session)

    @property
    def trained_methods(self) -> tuple[str, ...]:
        """Classical methods of the training set (from the metadata; all three when not recorded)."""
        return tuple(self.training.get("methods") or ("mf", "mw", "nt"))

    def serves(self, method: str) -> bool:
        """Whether the network refines ``method``'s order: a method of its training set, or NT for a DP-TPU
        model trained on MF (NT reaches the network in the MF representation, :mod:`dptpu.models.nt_prior`)."""
        return method in self.trained_methods or (method == "nt" and self.kind == "dptpu"
                                                  and "mf" in self.trained_methods)

    @property
    def input_names(self) -> tuple[str, ...]:
        return tuple(i.name for i in self._session.get_inputs())

    def predict(self, wrapped_high, wrapped_low, coarse_order, frequency_high) -> np.ndarray:
        """The network's continuous fringe order, ``(H, W)`` float32 or ``(B, H, W)`` for batched input.

        Parameters
        ----------
        wrapped_high, wrapped_low : ndarray (H, W) or (B, H, W)
            Wrapped phases in radians, ``[0, 2pi)``; must be finite (see :meth:`refine` for masking).
        coarse_order : ndarray (H, W) or (B, H, W)
            The classical method's fringe order of the high frequency.
        frequency_high : float or ndarray (B,)
            High frequency, periods across the projector.
        """
        arrays = [np.asarray(a, dtype=np.float32) for a in (wrapped_high, wrapped_low, coarse_order)]
        shape = arrays[0].shape
        if arrays[0].ndim not in (2, 3) or any(a.shape != shape for a in arrays):
            raise ValueError("wrapped_high, wrapped_low and coarse_order must share a shape (H, W) or (B, H, W); "
                             f"got {[a.shape for a in arrays]}")
        batched = arrays[0].ndim == 3
        images = [a if batched else a[None] for a in arrays]  # (B, H, W)
        batch = images[0].shape[0]
        frequency = np.broadcast_to(np.asarray(frequency_high, dtype=np.float32).reshape(-1), (batch,)).copy()
        if not np.all(frequency > 0):
            raise ValueError(f"frequency_high must be > 0; got {frequency_high!r}")
        inputs = {"wrapped_high": images[0][:, None], "wrapped_low": images[1][:, None],
                  "coarse_order": images[2][:, None], "frequency_high": frequency}
        feeds = {name: inputs[name] for name in self.input_names}
        out = self._session.run(None, feeds)[0][:, 0]  # (B, H, W)
        return out if batched else out[0]

    def refine(self, wrapped_high, wrapped_low, coarse_order, frequency_high, *, valid=None) -> np.ndarray:
        """Refined integer fringe order ``(H, W)`` int32: the network's output rounded on valid pixels.

        Parameters
        ----------
        wrapped_high, wrapped_low : ndarray (H, W)
            Wrapped phases in radians ``[0, 2pi)``, float32 or float64; NaN allowed where ``valid`` is False.
        coarse_order : ndarray (H, W)
            Classical fringe order (Eq. (5), (7) or (9)): integers, or floats (NaN allowed where not valid).
        frequency_high : float
            Periods across the projector.
        valid : ndarray (H, W) bool, optional
            Pixels to refine; elsewhere the network sees 0 and the classical order is kept. Default: the
            pixels where all three inputs are finite.

        Notes
        -----
        One pass per input map: the masked copy is made in the input's dtype and cast to the network's
        float32 (480x640: about a third of the previous float64 masking's cost, docs/benchmarks.md).
        """
        arrays = [np.asarray(a) for a in (wrapped_high, wrapped_low, coarse_order)]
        if arrays[0].ndim != 2 or any(a.shape != arrays[0].shape for a in arrays):
            raise ValueError("refine takes (H, W) maps of one shape; got wrapped_high, wrapped_low, coarse_order "
                             f"shapes {[a.shape for a in arrays]}")
        floating = [a for a in arrays if not np.issubdtype(a.dtype, np.integer)]
        mask = np.ones(arrays[0].shape, bool) if valid is None else np.array(valid, dtype=bool)
        for a in floating:
            mask &= np.isfinite(a)
        high, low, order = (np.where(mask, a, 0).astype(np.float32, copy=False) for a in arrays)
        continuous = self.predict(high, low, order, float(frequency_high))
        rounded = np.rint(continuous, out=continuous).astype(np.int32)
        coarse = arrays[2]
        if np.issubdtype(coarse.dtype, np.integer):
            classical = coarse
        else:
            finite = np.isfinite(coarse)
            classical = np.rint(np.where(finite, coarse, 0)).astype(np.int32)
        return np.where(mask, rounded, classical).astype(np.int32, copy=False)
