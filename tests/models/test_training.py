"""Training: a step lowers the loss, resume is bit-exact, two DDP processes equal one process."""
import itertools
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from dptpu.models.dataset_loader import FringeOrderDataset, collate, epoch_order
from dptpu.models.factory import build_model
from dptpu.models.loss import fringe_order_loss
from dptpu.models.training import TrainOptions, train

from .conftest import TINY_DPTPU


def _options(data, tmp_path, name, **extra):
    values = {"data_dir": data, "out": None, "checkpoint": tmp_path / f"{name}.ckpt", "epochs": 2, "batch": 2,
              "crop": (32, 32), "seed": 5, "model": "dptpu", "config": TINY_DPTPU, "progress": False}
    values.update(extra)
    return TrainOptions(**values)


def _checkpoint(path):
    return torch.load(path, map_location="cpu", weights_only=True)


def test_training_steps_lower_the_loss_on_a_tiny_dataset(tiny_dataset):
    dataset = FringeOrderDataset(tiny_dataset, crop=(64, 64))
    batch = collate([dataset.item(i, 0) for i in range(len(dataset))])
    torch.manual_seed(0)
    model = build_model("dptpu", TINY_DPTPU)
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-3)
    args = (batch["wrapped_high"], batch["wrapped_low"], batch["coarse_order"], batch["frequency_high"])
    losses = []
    for _ in range(4):
        terms = fringe_order_loss(model(*args), batch["label_order"], batch["valid"])
        optimizer.zero_grad()
        terms.total.backward()
        optimizer.step()
        losses.append(float(terms.total.detach()))
    assert losses[0] > 100  # NT's coarse orders at 1 sigma are far off on many pixels
    assert all(b < a for a, b in itertools.pairwise(losses))  # every AdamW step lowers it


def test_samples_reach_dptpu_with_the_priors_of_inference(tiny_dataset):
    raw = FringeOrderDataset(tiny_dataset)
    converted = FringeOrderDataset(tiny_dataset, dptpu_priors=True)
    for index, sample in enumerate(raw.samples):
        item, mf = raw.item(index, 0), converted.item(index, 0)
        valid = item["valid"]
        right = [float((i["coarse_order"] == i["label_order"])[valid].float().mean()) for i in (item, mf)]
        if sample.method == "mf":  # the order read at the projector's ends: the same away from them
            assert torch.equal(item["wrapped_low"], mf["wrapped_low"]) and right[1] >= right[0]
        else:  # NT at 1 sigma on 64x64 step scenes, right orders lookup -> band prior (measured): f_h = 80
            # 63.1 -> 99.2 % and 24.9 -> 95.8 %; f_h = 32 93.8 -> 89.8 % and 98.6 -> 98.1 % (small bands)
            beyond = float((mf["wrapped_low"][valid] > 2 * np.pi * 1.01).float().mean())
            assert beyond < 0.01  # one period across the projector (measured: 1 pixel of 3,726 beyond it)
            assert right[1] > 0.85 and (sample.frequency_high < 50 or right[1] > max(0.95, right[0] + 0.3))


def test_crops_and_order_are_a_function_of_seed_epoch_and_index(tiny_dataset):
    a = FringeOrderDataset(tiny_dataset, crop=(32, 40), seed=1)
    b = FringeOrderDataset(tiny_dataset, crop=(32, 40), seed=1)
    assert torch.equal(a.item(3, 7)["wrapped_high"], b.item(3, 7)["wrapped_high"])
    assert not torch.equal(a.item(3, 7)["wrapped_high"], a.item(3, 8)["wrapped_high"])
    assert a.item(0, 0)["label_order"].shape == (1, 32, 40)
    assert sorted(epoch_order(8, 1, 2)) == list(range(8))
    with pytest.raises(ValueError, match="crop 65x64 must fit in every sample"):
        FringeOrderDataset(tiny_dataset, crop=(65, 64))


def test_resume_continues_bit_exactly(tiny_dataset, tmp_path):
    whole = train(_options(tiny_dataset, tmp_path, "whole", epochs=2))
    first = train(_options(tiny_dataset, tmp_path, "part", epochs=1))
    resumed = train(_options(tiny_dataset, tmp_path, "resumed", epochs=2, resume=first.checkpoint))
    assert whole.epochs_done == resumed.epochs_done == 2 and first.epochs_done == 1
    a, b = _checkpoint(whole.checkpoint), _checkpoint(resumed.checkpoint)
    assert a["epoch"] == b["epoch"] == 2
    for key in a["model"]:
        assert torch.equal(a["model"][key], b["model"][key]), key
    for key, state in a["optimizer"]["state"].items():
        assert torch.equal(state["exp_avg"], b["optimizer"]["state"][key]["exp_avg"])
    assert [h["loss"] for h in a["history"]] == [h["loss"] for h in b["history"]]


def test_resume_rejects_a_checkpoint_of_another_model(tiny_dataset, tmp_path):
    first = train(_options(tiny_dataset, tmp_path, "part", epochs=1))
    with pytest.raises(ValueError, match="checkpoint holds a 'dptpu' model; --model is 'unet'"):
        train(_options(tiny_dataset, tmp_path, "u", model="unet", config=None, resume=first.checkpoint))
    broken = tmp_path / "broken.ckpt"
    broken.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="broken.ckpt: not a dptpu training checkpoint"):
        train(_options(tiny_dataset, tmp_path, "b", resume=broken))


def _all_valid_copy(source: Path, target: Path) -> Path:
    """The dataset with every pixel valid, so each process's loss has the same number of pixels."""
    shutil.copytree(source, target)
    for path in (target / "samples").glob("*.npz"):
        with np.load(path) as archive:
            data = dict(archive)
        data["valid"] = np.ones_like(data["valid"])
        np.savez(path, **data)
    return target


def test_two_ddp_processes_train_like_one_process_with_the_global_batch(tiny_dataset, tmp_path):
    data = _all_valid_copy(tiny_dataset, tmp_path / "data")
    single = train(_options(data, tmp_path, "single", epochs=1, batch=2))
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
               "-m", "dptpu.cli.main", "train", "--data", str(data), "--out", str(tmp_path / "ddp.onnx"),
               "--checkpoint", str(tmp_path / "ddp.ckpt"), "--epochs", "1", "--batch", "1", "--crop-size", "32x32",
               "--seed", "5", "--config", ('{"widths": [8, 8, 8, 8], "depths": [1, 1, 1, 1], "heads": [1, 1, 1, 2], '
               '"decoder_width": 8}'), "--threads", "1", "--quiet"]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=240, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "2 process(es)" in done.stdout and (tmp_path / "ddp.onnx").is_file()
    a, b = _checkpoint(single.checkpoint), _checkpoint(tmp_path / "ddp.ckpt")
    assert a["options"]["world_size"] == 1 and b["options"]["world_size"] == 2
    for key in a["model"]:
        assert torch.allclose(a["model"][key], b["model"][key], atol=1e-5, rtol=1e-4), key
    assert b["history"][0]["loss"] == pytest.approx(a["history"][0]["loss"], rel=1e-4)
