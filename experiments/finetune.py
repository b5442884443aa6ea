"""Fine-tune a trained fringe-order network on a twin set, from its weights, with a fixed budget of steps.

The start point is a training checkpoint (``dptpu-checkpoint/1``) or an exported ONNX model whose weights are
read back (:func:`dptpu.models.onnx_weights.load_onnx_model`). Fine-tuning is :func:`dptpu.models.training.train`
resumed from a checkpoint written here: the start weights, a fresh AdamW state at the fine-tuning learning rate,
epoch 0. Two fine-tunes with the same options on two sets of the same size take the same steps on the same crops
(crops and order are functions of ``(seed, epoch, index)``), so a difference between them is the data's.

Imports torch (through :mod:`dptpu.models`) only when called: the downstream comparison's other steps and its
importers do not need it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["FinetuneOptions", "load_start_model", "finetune"]


@dataclass(frozen=True)
class FinetuneOptions:
    """Budget of a fine-tune: ``epochs`` over the set in steps of ``batch`` crops of ``crop`` (height, width)
    pixels, AdamW at ``lr``, ``seed`` of crops and order; ``huber``: the loss' Huber threshold in orders
    (:class:`dptpu.models.loss.LossWeights`; None: the paper's squared error)."""

    epochs: int = 60
    batch: int = 4
    crop: tuple = (64, 64)
    lr: float = 3e-4
    seed: int = 0
    huber: float | None = None

    def __post_init__(self):
        if int(self.epochs) < 1 or int(self.batch) < 1:
            raise ValueError(f"--epochs and --batch must be >= 1; got {self.epochs}, {self.batch}")
        if not self.lr > 0:
            raise ValueError(f"--lr must be > 0; got {self.lr}")
        if self.huber is not None and not self.huber > 0:
            raise ValueError(f"--huber must be > 0 orders; got {self.huber}")


def load_start_model(path):
    """``(model, kind, config, source)``: the network to fine-tune from an ``.onnx`` model or a ``.ckpt``.

    ValueError (naming the file) when neither can be read as a dptpu network.
    """
    from dptpu.models.factory import model_config  # torch

    path = Path(path)
    if path.suffix == ".onnx":
        from dptpu.models.onnx_weights import load_onnx_model  # torch, onnx

        model, training = load_onnx_model(path)
        return model, training["kind"], model_config(model), {"onnx": str(path),
                                                              "max_abs_difference": training["max_abs_difference"]}
    from dptpu.models.export import load_checkpoint_model  # torch

    model, checkpoint = load_checkpoint_model(path)
    return model, checkpoint["kind"], model_config(model), {"checkpoint": str(path),
                                                            "epoch": int(checkpoint.get("epoch", 0))}


def finetune(start, data_dir, out_onnx, options: FinetuneOptions = FinetuneOptions(), *,
             progress: bool = False) -> dict:
    """Fine-tune ``start`` (a path, or a ``(model, kind, config, source)`` tuple) on ``data_dir``; export to
    ``out_onnx``. Returns the run's record: steps, seconds, first and last epoch loss. ``progress``: the training's
    bar and epoch lines on stderr (:func:`dptpu.models.training.train`)."""
    import torch  # training only

    from dptpu.models.loss import LossWeights  # torch
    from dptpu.models.training import CHECKPOINT_FORMAT, TrainOptions, train  # torch

    model, kind, config, source = start if isinstance(start, tuple) else load_start_model(start)
    out_onnx = Path(out_onnx)
    start_checkpoint = out_onnx.with_name(out_onnx.stem + ".start.ckpt")
    optimizer = torch.optim.AdamW(model.parameters(), lr=float(options.lr), weight_decay=0.01)
    torch.save({"format": CHECKPOINT_FORMAT, "kind": kind, "config": config, "epoch": 0,
                "model": model.state_dict(), "optimizer": optimizer.state_dict(), "history": [],
                "options": {"finetune_from": source}, "dataset": {}}, start_checkpoint)
    result = train(TrainOptions(data_dir=Path(data_dir), out=out_onnx, epochs=int(options.epochs),
                                batch=int(options.batch), crop=tuple(options.crop) if options.crop else None,
                                seed=int(options.seed), model=kind, lr=float(options.lr),
                                loss=LossWeights(huber=None if options.huber is None else float(options.huber)),
                                resume=start_checkpoint, checkpoint=out_onnx.with_suffix(".ckpt"), progress=progress))
    samples = len(list((Path(data_dir) / "samples").glob("*.npz")))
    return {"onnx": str(result.onnx), "epochs": result.epochs_done,
            "steps": result.epochs_done * (samples // int(options.batch)), "seconds": round(result.seconds, 1),
            "loss_first_epoch": result.history[0]["loss"] if result.history else None,
            "loss_last_epoch": result.history[-1]["loss"] if result.history else None, "start": source}
