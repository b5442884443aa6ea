"""Twin datasets (dptpu-dataset/1): files and keys, labels against the ray cast, noise, shards, bad input."""
import numpy as np
import pytest
import yaml

from dptpu.cli.main import main
from dptpu.fpp.dataset import DATASET_FORMAT, SAMPLE_ARRAYS, SAMPLE_RIG, SAMPLE_SCALARS, open_dataset
from dptpu.sim.dataset import DatasetSpec, parse_shard, scene_seed, write_dataset
from dptpu.sim.raycast import trace
from dptpu.sim.rig import nominal_rig
from dptpu.sim.scenes import random_scene

SIZE = (96, 72)
SPEC = DatasetSpec(frequencies=(32, 64), methods=("mf", "mw", "nt"), scenes=2, noise=(0.0, 3.1386), size=SIZE,
                   seed=5)


@pytest.fixture(scope="module")
def rig():
    return nominal_rig()


@pytest.fixture(scope="module")
def dataset_dir(rig, tmp_path_factory):
    return write_dataset(rig, SPEC, tmp_path_factory.mktemp("ds") / "set", progress=False)


def _by_key(dataset):
    return {(s.scene_seed, s.frequency_high, s.method, s.noise_sigma): s for s in dataset}


def test_files_and_keys_are_as_documented(dataset_dir):
    meta = yaml.safe_load((dataset_dir / "dataset.yaml").read_text())
    assert meta["format"] == DATASET_FORMAT and meta["rig"] == "rig.yaml"
    assert meta["count"] == 2 * 2 * 3 * 2 and meta["per_scene"] == 12 and meta["shards"] == 1
    assert meta["frequencies"] == [32.0, 64.0] and meta["methods"] == ["mf", "mw", "nt"]
    assert meta["noise"] == [0.0, 3.1386] and meta["size"] == list(SIZE) and meta["seed"] == 5
    assert meta["input_steps"] == 3 and meta["label_steps"] == 12
    names = sorted(p.name for p in (dataset_dir / "samples").glob("*.npz"))
    assert names == [f"0-{i:06d}.npz" for i in range(24)]
    dataset = open_dataset(dataset_dir)
    assert len(dataset) == 24 and dataset.missing == 0
    assert dataset.rig.camera.size == SIZE
    with np.load(dataset.paths[0]) as archive:
        assert set(archive.files) == set(SAMPLE_ARRAYS + SAMPLE_SCALARS + (SAMPLE_RIG,))
        dtypes = {k: archive[k].dtype for k in SAMPLE_ARRAYS}
    assert dtypes == {"wrapped_high": np.float32, "wrapped_low": np.float32, "coarse_order": np.float32,
                      "label_order": np.int16, "valid": np.bool_}
    sample = dataset[13]  # scene 1, combination 1: f 32, mf, noise 3.1386
    assert (sample.frequency_high, sample.method, sample.noise_sigma) == (32.0, "mf", 3.1386)
    assert sample.scene_seed == scene_seed(5, 1) and sample.rig == "rig"  # an unnamed Rig
    assert meta["rigs"] == [{"name": "rig", "file": "rig.yaml", "scenes": 2}] and dataset.rig_names == ["rig"]
    lows = {(s.method, s.frequency_high): s.frequency_low for s in dataset}
    assert lows == {("mf", 32.0): 1.0, ("mf", 64.0): 1.0, ("mw", 32.0): 31.0, ("mw", 64.0): 63.0,
                    ("nt", 32.0): 10.9, ("nt", 64.0): 10.9}
    for s in dataset:
        for key in ("wrapped_high", "wrapped_low"):
            assert getattr(s, key).shape == (SIZE[1], SIZE[0])
            assert getattr(s, key).min() >= 0 and getattr(s, key).max() < 2 * np.pi
        assert s.valid.mean() > 0.2


def test_labels_agree_with_the_ray_cast_on_noiseless_valid_pixels(rig, dataset_dir):
    dataset = open_dataset(dataset_dir)
    twin = dataset.rig
    for scene_index in range(2):
        seed = scene_seed(5, scene_index)
        samples = trace(twin, random_scene(twin, seed))
        x_p = samples.projector_xy[..., 0]
        for s in dataset:
            if s.scene_seed != seed or s.noise_sigma != 0.0:
                continue
            valid, f = s.valid, s.frequency_high
            true_phase = 2 * np.pi * f * x_p[valid] / 912
            absolute = s.wrapped_high[valid] + 2 * np.pi * s.label_order[valid]
            error = np.abs(absolute - true_phase)  # the input phase made absolute, radians
            assert np.median(error) < 0.01 and error.max() < 0.3  # 8-bit quantization; a wrong order is 2 pi
            true_order = np.floor(f * x_p[valid] / 912)
            assert np.mean(s.label_order[valid] == true_order) > 0.995  # differs only at the wraps
            assert not (valid & ~samples.lit).any()
            assert s.label_rejected == 0  # noise-free 12-step labels of an effect-free rig are all right


def test_classical_coarse_order_errors_increase_with_noise(dataset_dir):
    samples = _by_key(open_dataset(dataset_dir))
    rates = {}
    for (_seed, f, method, sigma), s in samples.items():
        valid = s.valid
        wrong = np.count_nonzero(s.coarse_order[valid] != s.label_order[valid])
        rates.setdefault((f, method, sigma), []).append(wrong / valid.sum())
    rate = {k: float(np.mean(v)) for k, v in rates.items()}
    for f in (32.0, 64.0):
        for method in ("mf", "mw", "nt"):
            assert rate[(f, method, 3.1386)] > rate[(f, method, 0.0)]
    # measured (2 scenes, 96x72): MF 64 ~0.1 % -> ~40 %; MW more fragile than MF; NT fails most
    assert rate[(64.0, "mf", 0.0)] < 0.01 and rate[(64.0, "mf", 3.1386)] > 0.1
    assert rate[(64.0, "mw", 3.1386)] > rate[(64.0, "mf", 3.1386)]
    assert rate[(64.0, "mf", 3.1386)] > rate[(32.0, "mf", 3.1386)]


def test_shards_merged_equal_the_unsharded_set(rig, tmp_path):
    spec = DatasetSpec(frequencies=(48,), methods=("mf",), scenes=3, noise=(1.5693,), size=SIZE, seed=2)
    whole = open_dataset(write_dataset(rig, spec, tmp_path / "whole", progress=False))
    merged_dir = tmp_path / "merged"
    write_dataset(rig, spec, merged_dir, shard=(0, 2), workers=2, progress=False)  # scenes 0 and 2, 2 processes
    write_dataset(rig, spec, merged_dir, shard=(1, 2), progress=False)
    merged = open_dataset(merged_dir)
    assert [p.name for p in merged.paths] == ["0-000000.npz", "1-000001.npz", "0-000002.npz"]
    assert len(merged) == len(whole) == 3
    for a, b in zip(whole, merged):
        for key in SAMPLE_ARRAYS:
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
        assert a.scene_seed == b.scene_seed and a.method == b.method


def test_a_partial_shard_reports_missing_samples_and_resumes(rig, tmp_path):
    spec = DatasetSpec(frequencies=(48,), methods=("mw",), scenes=2, noise=(0.0,), size=SIZE, seed=1)
    out = write_dataset(rig, spec, tmp_path / "set", shard=(1, 2), progress=False)
    dataset = open_dataset(out)
    assert len(dataset) == 1 and dataset.missing == 1
    stamp = dataset.paths[0].stat().st_mtime_ns
    write_dataset(rig, spec, out, shard=(1, 2), progress=False)  # nothing left to render
    assert dataset.paths[0].stat().st_mtime_ns == stamp


def test_bad_arguments_give_clear_errors(rig, tmp_path, capsys):
    base = ["sim", "dataset", "--rig", "nominal", "--scenes", "1", "--size", "96x72", "--quiet"]
    cases = [
        (["--shard", "2/2"], "--shard must be I/N with 0 <= I < N"),
        (["--methods", "mf,xx"], "--methods must list distinct methods among mf, mw, nt"),
        (["--noise", "-1"], "--noise must list one or more sigmas >= 0"),
        (["--noise", "1", "2"], "--noise takes one comma-separated list: --noise 1,2 (space-separated values are no "
                                "longer accepted)"),
        (["--input-steps", "2"], "--input-steps must be >= 3"),
        (["--frequencies", "32,abc"], "--frequencies must be comma-separated numbers"),
        (["--frequencies", "1"], "--frequencies: 1 must be > 1"),
        (["--workers", "0"], "--workers must be >= 1"),
        (["--meshes", str(tmp_path / "none")], "no such meshes folder"),
    ]
    for extra, message in cases:
        assert main(base + extra + ["--out", str(tmp_path / "bad")]) == 2, extra
        assert message in capsys.readouterr().err, extra
    with pytest.raises(ValueError, match="ambiguous NT pair"):
        write_dataset(rig, DatasetSpec(frequencies=(10.9 * 2,), methods=("nt",), size=SIZE), tmp_path / "nt",
                      progress=False)
    with pytest.raises(ValueError, match=r"--shard must be I/N"):
        parse_shard("1")


def test_a_folder_holding_another_dataset_is_refused(rig, tmp_path, capsys):
    spec = DatasetSpec(frequencies=(48,), methods=("mf",), scenes=1, noise=(0.0,), size=SIZE)
    out = write_dataset(rig, spec, tmp_path / "set", progress=False)
    code = main(["sim", "dataset", "--rig", "nominal", "--scenes", "1", "--size", "96x72", "--frequencies", "48",
                 "--methods", "mf", "--noise", "0", "--seed", "7", "--quiet", "--out", str(out)])
    assert code == 2
    assert "seed is 0 but this run has 7" in capsys.readouterr().err


def test_open_dataset_rejects_folders_that_are_not_datasets(tmp_path):
    with pytest.raises(FileNotFoundError, match="dataset.yaml: no such file"):
        open_dataset(tmp_path)
    (tmp_path / "dataset.yaml").write_text("format: something-else\n")
    with pytest.raises(ValueError, match="format must be 'dptpu-dataset/1'; got 'something-else'"):
        open_dataset(tmp_path)


def test_cli_writes_a_dataset_with_a_progress_bar(tmp_path, capsys):
    code = main(["sim", "dataset", "--rig", "nominal", "--scenes", "1", "--size", "96x72", "--frequencies", "64",
                 "--methods", "nt", "--noise", "1.5693", "--out", str(tmp_path / "set")])
    assert code == 0
    captured = capsys.readouterr()
    assert "1 of 1 samples on disk" in captured.out
    assert "dataset: 100%" in captured.err and "1/1" in captured.err  # the tqdm bar
    sample = open_dataset(tmp_path / "set")[0]
    assert sample.method == "nt" and sample.frequency_low == 10.9


def test_open_dataset_rejects_duplicate_indices_and_misnamed_samples(dataset_dir, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    (copy / "samples").mkdir(parents=True)
    shutil.copy(dataset_dir / "dataset.yaml", copy / "dataset.yaml")
    shutil.copy(dataset_dir / "samples" / "0-000003.npz", copy / "samples" / "0-000003.npz")
    assert len(open_dataset(copy)) == 1 and open_dataset(copy).missing == 23
    shutil.copy(dataset_dir / "samples" / "0-000003.npz", copy / "samples" / "1-000003.npz")
    with pytest.raises(ValueError, match="index 3 is also in 0-000003.npz"):
        open_dataset(copy)
    (copy / "samples" / "1-000003.npz").rename(copy / "samples" / "sample3.npz")
    with pytest.raises(ValueError, match="sample3.npz: sample files must be named <shard>-<index:06d>.npz"):
        open_dataset(copy)
