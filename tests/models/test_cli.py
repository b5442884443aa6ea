"""``dptpu train``, ``dptpu model export|eval|toy-data`` and ``dptpu unwrap --model`` in-process."""
import csv
import json
import re

import numpy as np
import pytest

from dptpu.cli.main import main
from dptpu.fpp.dataset import list_samples, read_sample
from tests.cli.terminal import run_on_a_terminal

from .conftest import TINY_DPTPU

MF = [{"frequency": 64}, {"frequency": 1}]


def _run(capsys, argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_train_then_export_then_eval(tiny_dataset, tmp_path, capsys):
    out = tmp_path / "m.onnx"
    code, stdout, stderr = _run(capsys, ["train", "--data", tiny_dataset, "--out", out, "--epochs", 1, "--batch", 4,
                                         "--crop-size", "48x32", "--config", json.dumps(TINY_DPTPU), "--threads", 1])
    assert code == 0, stderr
    assert stdout.startswith("dptpu: 1 epochs,") and f"-> {out}" in stdout
    assert "epoch 1/1" in stderr  # the progress bar
    assert out.is_file() and (tmp_path / "m.ckpt").is_file()

    code, stdout, _ = _run(capsys, ["model", "export", "--checkpoint", tmp_path / "m.ckpt",
                                    "--out", tmp_path / "e.onnx"])
    assert code == 0 and stdout.strip() == f"dptpu (epoch 1) -> {tmp_path / 'e.onnx'}"
    # on a terminal: its stages on stderr (seconds of torch's import and the export), the summary alone on stdout
    code, stdout, shown = run_on_a_terminal(["model", "export", "--checkpoint", tmp_path / "m.ckpt",
                                             "--out", tmp_path / "t.onnx"], tmp_path)
    assert code == 0 and stdout == f"dptpu (epoch 1) -> {tmp_path / 't.onnx'}\n", shown
    for stage in (f"reading {tmp_path / 'm.ckpt'}", f"exporting to {tmp_path / 't.onnx'}", "done"):
        assert re.search(rf"model export: step \d \[[\d:]+\] {re.escape(stage)}", shown), shown
    from dptpu.models.inference import FringeOrderModel

    for path in (out, tmp_path / "e.onnx"):  # the model's domain travels in its metadata
        loaded = FringeOrderModel.load(path)
        assert loaded.trained_methods == ("mf", "nt") and loaded.training["frequencies"] == [32.0, 80.0]

    code, stdout, _ = _run(capsys, ["model", "eval", "--data", tiny_dataset, "--model", out, "--out", tmp_path / "ev"])
    assert code == 0 and "| method | f_h | noise | classical | classical+median | dptpu |" in stdout
    with open(tmp_path / "ev" / "table.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert {r["solver"] for r in rows} == {"classical", "classical+median", "dptpu"}
    assert len(rows) == 3 * 4  # (mf, nt) x (32, 80) groups, three solvers
    # the classical accuracy is the share of valid pixels whose coarse order equals the label
    samples = [read_sample(p) for p in list_samples(tiny_dataset)]
    mf32 = [s for s in samples if s.method == "mf" and s.frequency_high == 32]
    correct = sum(int(((s.coarse_order == s.label_order) & s.valid).sum()) for s in mf32)
    total = sum(int(s.valid.sum()) for s in mf32)
    row = next(r for r in rows if r["method"] == "mf" and r["frequency"] == "32" and r["solver"] == "classical")
    assert float(row["accuracy"]) == pytest.approx(correct / total, abs=1e-6) and int(row["pixels"]) == total


def test_train_rejects_bad_arguments(tiny_dataset, tmp_path, capsys):
    code, _, stderr = _run(capsys, ["train", "--data", tiny_dataset, "--out", tmp_path / "m.onnx", "--crop-size",
                                    "32x99", "--config", json.dumps(TINY_DPTPU)])
    assert code == 2 and stderr.strip().endswith("(smallest 64x64)") and stderr.count("\n") == 1
    code, _, stderr = _run(capsys, ["train", "--data", tmp_path, "--out", tmp_path / "m.onnx"])
    assert code == 2 and "no dataset.yaml" in stderr
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--data", str(tiny_dataset), "--out", "m.onnx", "--crop-size", "64by64"])
    assert exit_info.value.code == 2
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_info:  # the old spelling, HEIGHTxWIDTH, is refused with the new one
        main(["train", "--data", str(tiny_dataset), "--out", "m.onnx", "--crop", "64x32"])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err == ("dptpu train: error: --crop is no longer accepted; write --crop-size "
                                       "WIDTHxHEIGHT (width first; --crop was HEIGHTxWIDTH)\n")


def test_toy_data_writes_a_dataset(tmp_path, capsys):
    code, _stdout, _ = _run(capsys, ["model", "toy-data", "--out", tmp_path / "d", "--scenes", 1, "--frequencies", "96",
                                    "--methods", "mw", "--size", "48x40", "--noise", "1.5693,3.1386"])
    assert code == 0
    samples = [read_sample(p) for p in list_samples(tmp_path / "d")]
    assert [(s.method, s.frequency_high, s.frequency_low, s.noise_sigma) for s in samples] == [
        ("mw", 96.0, 95.0, 1.5693), ("mw", 96.0, 95.0, 3.1386)]
    assert samples[0].valid.shape == (40, 48)


def test_unwrap_with_a_model_records_it_and_none_gives_the_classical_result(synthetic_capture, tiny_onnx, tmp_path,
                                                                            capsys):
    folder, scene = synthetic_capture(MF)
    code, _, stderr = _run(capsys, ["unwrap", "--capture", folder, "--method", "mf", "--model", "none",
                                    "--out", tmp_path / "classical.npz"])
    assert code == 0, stderr
    code, _stdout, stderr = _run(capsys, ["unwrap", "--capture", folder, "--method", "mf", "--model", tiny_onnx[0],
                                         "--out", tmp_path / "model.npz"])
    assert code == 0, stderr
    with np.load(tmp_path / "classical.npz") as classical, np.load(tmp_path / "model.npz") as refined:
        assert str(classical["model"]) == "none" and str(refined["model"]) == str(tiny_onnx[0])
        assert str(refined["method"]) == "mf"
        # the synthetic capture is noise-free enough for MF to be exact on every lit pixel
        assert classical["valid"].sum() == scene.lit.sum()
        # the untrained random-head model changes orders; absolute phase stays psi + 2 pi k on valid pixels
        valid = refined["valid"]
        assert not np.array_equal(refined["fringe_order"][valid], classical["fringe_order"][valid])
        psi = np.mod(classical["absolute_phase"], 2 * np.pi)
        np.testing.assert_allclose(refined["absolute_phase"][valid],
                                   psi[valid] + 2 * np.pi * refined["fringe_order"][valid], atol=1e-9)


def test_unwrap_with_a_bad_model_exits_2_and_the_classical_result_stays_available(synthetic_capture, tmp_path,
                                                                                 capsys):
    folder, _ = synthetic_capture(MF)
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(b"\x08\x07garbage")
    code, stdout, stderr = _run(capsys, ["unwrap", "--capture", folder, "--method", "mf", "--model", corrupt,
                                         "--out", tmp_path / "x.npz"])
    assert code == 2 and stdout == ""
    assert stderr.startswith("dptpu unwrap: error: ") and "corrupt.onnx: not a loadable ONNX model" in stderr
    code, _, stderr = _run(capsys, ["unwrap", "--capture", folder, "--method", "mf", "--model", tmp_path / "no.onnx",
                                    "--out", tmp_path / "x.npz"])
    assert code == 2 and "no.onnx: model file not found (pass --model none for the classical result)" in stderr
    code, _, _ = _run(capsys, ["unwrap", "--capture", folder, "--method", "mf", "--model", "none",
                               "--out", tmp_path / "x.npz"])
    assert code == 0


def test_unwrap_model_only_refines_two_frequency_methods(synthetic_capture, tiny_onnx, tmp_path, capsys):
    folder, _ = synthetic_capture([{"period": 16}, {"period": 17}, {"period": 18}])
    code, _, stderr = _run(capsys, ["unwrap", "--capture", folder, "--method", "heterodyne", "--model", tiny_onnx[0],
                                    "--out", tmp_path / "x.npz"])
    assert code == 2 and "--model refines the orders of mf, mw, nt; method 'heterodyne'" in stderr


def _scene(projector_px_per_pixel, shape=(48, 64)):
    from types import SimpleNamespace

    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    return SimpleNamespace(projector_x=(100.0 + projector_px_per_pixel * cols + 0.3 * rows), albedo=np.full(shape, 0.8),
                           lit=np.ones(shape, bool))


def test_fringe_density_is_periods_per_pixel(synthetic_capture):
    from dptpu.fpp.capture import read_capture
    from dptpu.fpp.reconstruct import unwrap_capture
    from dptpu.models.refine import fringe_density

    folder, _ = synthetic_capture(MF, scene=_scene(2.0))
    result = unwrap_capture(read_capture(folder), method="mf")
    # on the wrapped phase: 64 periods over 912 projector pixels, 2 projector pixels per camera column
    assert fringe_density(result.wrapped_phases[0], result.quality) == pytest.approx(64 * 2.0 / 912, rel=1e-3)
    # wrong orders on half of the pixels change nothing: the density never looks at an unwrapped phase
    assert fringe_density(result.wrapped_phases[0]) == pytest.approx(64 * 2.0 / 912, rel=1e-3)


@pytest.mark.skipif(__import__("dptpu.models.inference", fromlist=["x"]).shipped_model_path() is None,
                    reason="no shipped model models/dptpu.onnx")
@pytest.mark.parametrize("px_per_pixel,used", [(2.0, True), (10.0, False)])
def test_unwrap_uses_the_shipped_model_by_default_only_within_its_fringe_density(synthetic_capture, tmp_path, capsys,
                                                                               px_per_pixel, used):
    from dptpu.models.inference import shipped_model_path

    folder, scene = synthetic_capture(MF, scene=_scene(px_per_pixel))
    code, stdout, stderr = _run(capsys, ["unwrap", "--capture", folder, "--method", "mf", "--out", tmp_path / "x.npz"])
    assert code == 0, stderr
    # skipped with the reason: 10 projector px per camera px is 0.70 periods, folded by the wrapping to 0.30
    assert ("shipped model skipped: fringes of 0.30 periods per camera pixel" in stdout) != used
    with np.load(tmp_path / "x.npz") as result:
        assert str(result["model"]) == (str(shipped_model_path()) if used else "none")
        valid = result["valid"]
        truth = 2 * np.pi * 64 * scene.projector_x / 912  # absolute phase, radians
        error = np.abs(result["absolute_phase"][valid] - truth[valid])
        # 12 steps, tiny noise: every order is right, with or without the network (a wrong order is 2 pi off)
        assert valid.mean() > 0.99 and error.max() < 0.5
