"""Build a network by kind name and config dict (what checkpoints and ONNX metadata store)."""
from __future__ import annotations

from .network import DPTPUConfig, DPTPUNet
from .unet_baseline import UNetBaseline, UNetConfig

__all__ = ["MODEL_KINDS", "FringeOrderNet", "build_model", "model_config"]

#: ``dptpu``: the DP-TPU network (physics priors); ``unet``: the plain U-Net baseline.
MODEL_KINDS = ("dptpu", "unet")
#: A network of one of :data:`MODEL_KINDS`.
FringeOrderNet = DPTPUNet | UNetBaseline


def build_model(kind: str, config: dict | None = None) -> FringeOrderNet:
    """A freshly initialized network of ``kind`` with ``config`` (keys of its config dataclass)."""
    if kind == "dptpu":
        return DPTPUNet(DPTPUConfig.from_dict(config) if config else None)
    if kind == "unet":
        return UNetBaseline(UNetConfig.from_dict(config) if config else None)
    raise ValueError(f"model kind must be one of {', '.join(MODEL_KINDS)}; got {kind!r}")


def model_config(model: FringeOrderNet) -> dict:
    """The config dict that :func:`build_model` turns back into ``model``'s architecture."""
    return model.config.to_dict()
