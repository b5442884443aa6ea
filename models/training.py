"""Training of DP-TPU (or the U-Net baseline) on a twin dataset: AdamW, joint spatial-Fourier loss,
checkpoints every epoch, bit-exact resume, data-parallel with ``torchrun`` (DDP; gloo on CPU).

One epoch visits every sample once, in the order :func:`dptpu.models.dataset_loader.epoch_order`, in
steps of ``batch * world_size`` samples (the last incomplete step is dropped); in step ``s`` process
``r`` of ``world_size`` takes samples ``[s*G + r*batch, s*G + (r+1)*batch)`` of that order (``G`` the
global batch), and DDP averages the gradients. So two processes with ``batch`` b see the same global
batches as one process with batch ``2b``.

Reproducibility: the initial weights come from ``torch.manual_seed(seed)``; crops and sample order are a
function of ``(seed, epoch, index)``; nothing else is random. The checkpoint after epoch ``e`` holds the
model and optimizer state, so ``--resume`` continues with exactly the numbers of an uninterrupted run.
"""
from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
import torch.distributed as dist
from tqdm import tqdm

from .dataset_loader import FringeOrderDataset, collate, epoch_order
from .export import export_onnx
from .factory import MODEL_KINDS, build_model, model_config
from .loss import LossWeights, fringe_order_loss

__all__ = ["CHECKPOINT_FORMAT", "TrainOptions", "TrainResult", "default_checkpoint_path", "train"]

CHECKPOINT_FORMAT = "dptpu-checkpoint/1"


@dataclass
class TrainOptions:
    """Options of :func:`train` (the ``dptpu train`` flags).

    Attributes
    ----------
    data_dir : path
        ``dptpu-dataset/1`` folder.
    out : path or None
        ONNX file to export when training ends (rank 0); None = no export.
    epochs : int
        Total epochs (a resumed run continues up to this number).
    batch : int
        Samples per step and process.
    crop : (int, int) or None
        Training crop height, width in pixels.
    seed : int
    model : {"dptpu", "unet"}
    config : dict or None
        Architecture (keys of :class:`~dptpu.models.network.DPTPUConfig` or ``UNetConfig``); default sizes
        when None. Ignored on resume (the checkpoint's is used).
    lr : float
        AdamW learning rate (the paper: 1e-3).
    weight_decay : float
        AdamW weight decay.
    loss : LossWeights
        ``lambda1``, ``lambda2`` of Eq. (15); ``LossWeights(fourier=0)`` is the ablation.
    checkpoint : path or None
        Checkpoint written after every epoch; default :func:`default_checkpoint_path` of ``out``.
    resume : path or None
        Checkpoint to continue from.
    time_limit_s : float or None
        Stop after the first epoch that ends past this many seconds of training.
    progress : bool
        Progress bar on stderr (rank 0).
    """

    data_dir: Path
    out: Path | None = None
    epochs: int = 1
    batch: int = 4
    crop: tuple[int, int] | None = (64, 64)
    seed: int = 0
    model: str = "dptpu"
    config: dict | None = None
    lr: float = 1e-3
    weight_decay: float = 1e-2
    loss: LossWeights = field(default_factory=LossWeights)
    checkpoint: Path | None = None
    resume: Path | None = None
    time_limit_s: float | None = None
    progress: bool = True


@dataclass
class TrainResult:
    """What a run did: epochs completed (in total, counting resumed ones), per-epoch mean losses, files."""

    epochs_done: int
    history: list[dict]
    checkpoint: Path | None
    onnx: Path | None
    seconds: float
    parameters: int
    world_size: int


def default_checkpoint_path(out) -> Path:
    """``models/dptpu.onnx`` -> ``models/dptpu.ckpt``."""
    return Path(out).with_suffix(".ckpt")


def _check(options: TrainOptions) -> None:
    if options.model not in MODEL_KINDS:
        raise ValueError(f"--model must be one of {', '.join(MODEL_KINDS)}; got {options.model!r}")
    for name in ("epochs", "batch"):
        value = getattr(options, name)
        if not isinstance(value, int) or value < 1:
            raise ValueError(f"--{name} must be an integer >= 1; got {value!r}")
    if not (options.lr > 0):
        raise ValueError(f"learning rate must be > 0; got {options.lr!r}")


def _distributed() -> tuple[int, int]:
    """(rank, world size); starts the gloo process group under torchrun."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world > 1 and not dist.is_initialized():
        dist.init_process_group(backend="gloo")
    return (dist.get_rank(), dist.get_world_size()) if world > 1 else (0, 1)


class _Progress:
    """Progress on stderr: a tqdm bar per epoch (steps, running loss, rate), then the epoch's summary line."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.bar: tqdm | None = None

    def update(self, epoch: int, epochs: int, step: int, steps: int, loss: float) -> None:
        if not self.enabled:
            return
        if self.bar is None:
            self.bar = tqdm(total=steps, desc=f"epoch {epoch}/{epochs}", unit="step", file=sys.stderr, leave=False)
        self.bar.set_postfix(loss=f"{loss:.4f}", refresh=False)
        self.bar.update(1)

    def end_epoch(self, text: str) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        if self.enabled:
            tqdm.write(text, file=sys.stderr)


def _save_checkpoint(path: Path, state: dict) -> None:
    tmp = path.with_name(path.name + ".tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)


def _load_resume(path, options: TrainOptions) -> dict:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint (--resume)")
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 -- torch.load raises pickle, zip and runtime errors for a corrupt file
        raise ValueError(f"{path}: not a dptpu training checkpoint ({type(exc).__name__}: {exc})") from None
    if not isinstance(checkpoint, dict) or checkpoint.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{path}: not a dptpu training checkpoint (format {CHECKPOINT_FORMAT})")
    if checkpoint["kind"] != options.model:
        raise ValueError(f"{path}: checkpoint holds a {checkpoint['kind']!r} model; --model is {options.model!r}")
    return checkpoint


def train(options: TrainOptions) -> TrainResult:
    """Train a network; see :class:`TrainOptions`. Returns when ``epochs`` are done or time is up."""
    _check(options)
    started = time.perf_counter()
    rank, world = _distributed()
    dataset = FringeOrderDataset(options.data_dir, crop=options.crop, seed=options.seed,
                                 dptpu_priors=options.model == "dptpu")
    global_batch = options.batch * world
    steps = len(dataset) // global_batch
    if steps < 1:
        raise ValueError(f"{options.data_dir}: {len(dataset)} samples are fewer than one global batch of "
                         f"{global_batch} (batch {options.batch} x {world} processes)")

    checkpoint = _load_resume(options.resume, options) if options.resume else None
    torch.manual_seed(options.seed)
    model = build_model(options.model, checkpoint["config"] if checkpoint else options.config)
    optimizer = torch.optim.AdamW(model.parameters(), lr=options.lr, weight_decay=options.weight_decay)
    start_epoch, history = 0, []
    if checkpoint:
        model.load_state_dict(checkpoint["model"])
        optimizer.load_state_dict(checkpoint["optimizer"])
        start_epoch, history = int(checkpoint["epoch"]), list(checkpoint["history"])
    wrapped = torch.nn.parallel.DistributedDataParallel(model) if world > 1 else model
    checkpoint_path = Path(options.checkpoint) if options.checkpoint else (
        default_checkpoint_path(options.out) if options.out else None)
    progress = _Progress(options.progress and rank == 0)

    for epoch in range(start_epoch, options.epochs):
        model.train()
        order = epoch_order(len(dataset), options.seed, epoch)
        totals = {"loss": 0.0, "mse": 0.0, "fourier": 0.0}
        epoch_start = time.perf_counter()
        for step in range(steps):
            first = step * global_batch + rank * options.batch
            batch = collate([dataset.item(int(i), epoch) for i in order[first:first + options.batch]])
            pred = wrapped(batch["wrapped_high"], batch["wrapped_low"], batch["coarse_order"], batch["frequency_high"])
            terms = fringe_order_loss(pred, batch["label_order"], batch["valid"], options.loss)
            optimizer.zero_grad(set_to_none=True)
            terms.total.backward()
            optimizer.step()
            totals["loss"] += float(terms.total.detach())
            totals["mse"] += terms.mse
            totals["fourier"] += terms.fourier
            progress.update(epoch + 1, options.epochs, step + 1, steps, totals["loss"] / (step + 1))
        if world > 1:  # the mean over processes (each process's loss is the mean over its own batch)
            summed = torch.tensor([totals[k] for k in ("loss", "mse", "fourier")], dtype=torch.float64)
            dist.all_reduce(summed)
            totals = dict(zip(("loss", "mse", "fourier"), (summed / world).tolist()))
        record = {"epoch": epoch + 1, **{k: v / steps for k, v in totals.items()},
                  "seconds": round(time.perf_counter() - epoch_start, 3)}
        history.append(record)
        progress.end_epoch(f"epoch {epoch + 1}/{options.epochs}: loss {record['loss']:.5f} (mse {record['mse']:.5f}, "
                           f"fourier {record['fourier']:.5f}) in {record['seconds']:.1f} s")
        if rank == 0 and checkpoint_path is not None:
            _save_checkpoint(checkpoint_path, {
                "format": CHECKPOINT_FORMAT, "kind": options.model, "config": model_config(model),
                "epoch": epoch + 1, "model": model.state_dict(), "optimizer": optimizer.state_dict(),
                "history": history, "options": _options_record(options, world), "dataset": _dataset_record(dataset)})
        if options.time_limit_s is not None and time.perf_counter() - started > options.time_limit_s:
            break
    epochs_done = len(history)

    onnx_path = None
    if rank == 0 and options.out is not None:
        onnx_path = export_onnx(model, options.out, training={
            **_options_record(options, world), "epochs_done": epochs_done, "final": history[-1] if history else None,
            **_dataset_record(dataset)})
    if world > 1:
        dist.barrier()
    return TrainResult(epochs_done=epochs_done, history=history, checkpoint=checkpoint_path if rank == 0 else None,
                       onnx=onnx_path, seconds=time.perf_counter() - started,
                       parameters=sum(p.numel() for p in model.parameters()), world_size=world)


def _dataset_record(dataset: FringeOrderDataset) -> dict:
    """Methods, high frequencies and size of the training set (the model's domain, kept in its metadata)."""
    return {"methods": sorted({s.method for s in dataset.samples}),
            "frequencies": sorted({s.frequency_high for s in dataset.samples}), "samples": len(dataset)}


def _options_record(options: TrainOptions, world: int) -> dict:
    record = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(options).items()
              if k not in ("progress", "config")}
    record["crop"] = list(options.crop) if options.crop else None
    record["loss"] = {"mse": options.loss.mse, "fourier": options.loss.fourier, "huber": options.loss.huber}
    record["world_size"] = world
    return json.loads(json.dumps(record, default=str))
