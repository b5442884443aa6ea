"""The one reader of dptpu-dataset/1 (fpp.dataset): listing in name order, the Sample, checks on bad files."""
import numpy as np
import pytest
import yaml

from dptpu.fpp.dataset import DATASET_FORMAT, Sample, list_samples, open_dataset, read_dataset_yaml, read_sample


def _arrays(shape=(4, 5)):
    rng = np.random.default_rng(0)
    return {"wrapped_high": rng.uniform(0, 2 * np.pi, shape).astype(np.float32),
            "wrapped_low": rng.uniform(0, 2 * np.pi, shape).astype(np.float32),
            "coarse_order": np.full(shape, 3.0, np.float32), "label_order": np.full(shape, 3, np.int16),
            "valid": np.ones(shape, bool), "frequency_high": np.float64(32.0), "frequency_low": np.float64(1.0),
            "method": np.str_("mf")}


def _folder(tmp_path, samples: dict):
    (tmp_path / "samples").mkdir()
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"format": DATASET_FORMAT}))
    for name, arrays in samples.items():
        np.savez_compressed(tmp_path / "samples" / name, **arrays)
    return tmp_path


def test_a_minimal_sample_reads_with_defaults_for_the_optional_keys(tmp_path):
    folder = _folder(tmp_path, {"b_toy.npz": _arrays(), "a_toy.npz": _arrays()})
    paths = list_samples(folder)
    assert [p.name for p in paths] == ["a_toy.npz", "b_toy.npz"]  # name order, any names
    sample = read_sample(paths[0])
    assert isinstance(sample, Sample) and sample.name == "a_toy" and sample.method == "mf"
    assert np.isnan(sample.noise_sigma) and sample.scene_seed == -1 and sample.label_rejected == -1
    assert sample.rig is None and sample.wrapped_high.dtype == np.float32 and sample.label_order.dtype == np.int16


def test_non_finite_pixels_become_invalid_and_zero(tmp_path):
    arrays = _arrays()
    arrays["wrapped_high"][1, 2] = np.nan
    arrays["coarse_order"][0, 0] = np.inf
    sample = read_sample(_folder(tmp_path, {"0-000000.npz": arrays}) / "samples" / "0-000000.npz")
    assert not sample.valid[1, 2] and not sample.valid[0, 0] and sample.valid.sum() == 18
    assert sample.wrapped_high[1, 2] == 0 and sample.coarse_order[0, 0] == 0 and sample.label_order[0, 0] == 0


def test_the_twin_view_orders_by_index_and_names_an_unnamed_rig(tmp_path):
    folder = _folder(tmp_path, {"1-000001.npz": {**_arrays(), "rig": np.str_("wide")}, "0-000002.npz": _arrays()})
    dataset = open_dataset(folder)
    assert [p.name for p in dataset.paths] == ["1-000001.npz", "0-000002.npz"]
    assert [s.rig for s in dataset] == ["wide", "rig"]  # a sample without its rig's name: the folder's first rig


def test_bad_folders_and_samples_give_errors_that_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="dataset.yaml: no such file"):
        read_dataset_yaml(tmp_path)
    arrays = _arrays()
    del arrays["method"]
    folder = _folder(tmp_path, {"x.npz": arrays})
    with pytest.raises(ValueError, match=r"x\.npz: missing keys \['method'\]"):
        read_sample(folder / "samples" / "x.npz")
    np.savez_compressed(folder / "samples" / "y.npz", **{**_arrays(), "method": np.str_("graycode")})
    with pytest.raises(ValueError, match="method must be mf, mw or nt; got 'graycode'"):
        read_sample(folder / "samples" / "y.npz")
    np.savez_compressed(folder / "samples" / "z.npz", **{**_arrays(), "valid": np.ones((3, 3), bool)})
    with pytest.raises(ValueError, match=r"valid must be a \(H, W\) array like wrapped_high"):
        read_sample(folder / "samples" / "z.npz")
    (folder / "dataset.yaml").write_text("format: something-else\n")
    with pytest.raises(ValueError, match="format must be 'dptpu-dataset/1'; got 'something-else'"):
        list_samples(folder)
