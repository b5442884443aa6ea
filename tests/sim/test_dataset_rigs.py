"""Datasets of several rigs: scenes split round robin, each sample names its rig, the wide rig's labels span every
fringe order; one-rig folders written before datasets named their rigs still read."""
import numpy as np
import pytest
import yaml

from dptpu.cli.main import main
from dptpu.cli.sim_dataset_cmd import rig_sources
from dptpu.fpp.dataset import open_dataset
from dptpu.sim.dataset import DatasetSpec, scene_rig, scene_seed, write_dataset
from dptpu.sim.rig import (
    dynamic_rig,
    load_twin_rig,
    nominal_rig,
    wide_rig,
    working_distance,
)

SIZE = (160, 120)
F_H = 32.0


@pytest.fixture(scope="module")
def two_rig_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("rigs") / "set"
    code = main(["sim", "dataset", "--rig", "nominal,wide", "--scenes", "2", "--size", f"{SIZE[0]}x{SIZE[1]}",
                 "--frequencies", f"{F_H:g}", "--methods", "mf", "--noise", "1.5693", "--seed", "100", "--quiet",
                 "--out", str(out)])
    assert code == 0
    return out


def _projector_share_seen(rig, depth_mm: float) -> float:
    """Share of the projector's width that the camera sees on the fronto-parallel plane z = depth_mm (camera
    frame): projector columns of the camera's left and right image edges through the principal point's row."""
    width, height = rig.camera.size
    u = np.array([-0.5, width - 0.5])
    rays = np.linalg.solve(rig.camera.K, np.stack([u, np.full(2, (height - 1) / 2), np.ones(2)]))  # (3, 2)
    points = rays * depth_mm / rays[2]
    p = rig.projector.K @ (rig.projector.R @ points + rig.projector.T[:, None])
    columns = np.sort(p[0] / p[2])
    return float((min(columns[1], rig.projector.size[0]) - max(columns[0], 0.0)) / rig.projector.size[0])


def test_the_wide_rig_sees_the_whole_projector_width_and_is_not_the_test_rig():
    wide, nominal, dynamic = wide_rig(), nominal_rig(), dynamic_rig()
    assert working_distance(wide) == pytest.approx(700.0, rel=1e-6)
    # pinhole model (distortion ignored): wide sees all of it from 0.9x to 1.25x the working distance (objects
    # and background); nominal only its middle part (docs/model-eval.md: ~47 %)
    for factor in (0.9, 1.0, 1.25):
        assert _projector_share_seen(wide, 700.0 * factor) == pytest.approx(1.0)
    assert _projector_share_seen(nominal, 800.0) == pytest.approx(0.47, abs=0.01)
    assert 0.75 < _projector_share_seen(dynamic, 600.0) < 0.85
    assert wide.camera.K[0, 0] == 1000.0 and dynamic.camera.K[0, 0] == pytest.approx(3895.8, abs=0.1)
    assert wide.projector.size != dynamic.projector.size
    assert load_twin_rig("wide", size=SIZE).camera.K[0, 0] == pytest.approx(250.0)


def test_a_two_rig_dataset_splits_scenes_and_names_each_samples_rig(two_rig_dir):
    meta = yaml.safe_load((two_rig_dir / "dataset.yaml").read_text())
    assert meta["rigs"] == [{"name": "nominal", "file": "rig-nominal.yaml", "scenes": 1},
                            {"name": "wide", "file": "rig-wide.yaml", "scenes": 1}]
    assert meta["rig"] == "rig-nominal.yaml" and not (two_rig_dir / "rig.yaml").exists()
    dataset = open_dataset(two_rig_dir)
    assert dataset.rig_names == ["nominal", "wide"] and len(dataset) == 2
    rigs = dataset.rigs
    assert rigs["wide"].camera.K[0, 0] == pytest.approx(250.0) and rigs["nominal"].camera.K[0, 0] == 650.0
    assert [s.rig for s in dataset] == ["nominal", "wide"]
    assert [scene_rig(i, 2) for i in range(2)] == [0, 1]
    assert [s.scene_seed for s in dataset] == [scene_seed(100, 0), scene_seed(100, 1)]


def test_wide_rig_labels_reach_order_zero_and_the_last_order(two_rig_dir):
    orders = {}
    for s in open_dataset(two_rig_dir):
        labels = s.label_order[s.valid]
        orders[s.rig] = (int(labels.min()), int(labels.max()))
    # measured (seed 100, 160x120, f_h = 32): wide 0..31, nominal 9..20
    assert orders["wide"] == (0, int(F_H) - 1)
    assert orders["nominal"][0] >= 5 and orders["nominal"][1] <= F_H - 6


def test_rig_flags_repeated_or_comma_separated_name_the_same_rigs(tmp_path, capsys):
    assert rig_sources(["nominal", "wide"]) == rig_sources(["nominal,wide"]) == [("nominal", "nominal"),
                                                                                ("wide", "wide")]
    assert rig_sources(["cam.mat,prj.mat"]) == [("cam", "cam.mat,prj.mat")]
    assert rig_sources([str(tmp_path / "my_rig.yaml")]) == [("my_rig", str(tmp_path / "my_rig.yaml"))]
    code = main(["sim", "dataset", "--rig", "wide", "--rig", "nominal,wide", "--scenes", "1", "--size", "96x72",
                 "--quiet", "--out", str(tmp_path / "bad")])
    assert code == 2 and "--rig: each rig may be given once" in capsys.readouterr().err
    with pytest.raises(ValueError, match="rig names must be distinct"):
        write_dataset([("a", nominal_rig()), ("a", wide_rig())], DatasetSpec(size=(96, 72)), tmp_path / "x")


def test_a_one_rig_folder_without_rig_names_still_reads_and_resumes(tmp_path):
    """A folder as written before datasets named their rigs: no ``rigs`` in dataset.yaml, no ``rig`` in samples."""
    spec = DatasetSpec(frequencies=(48,), methods=("mf",), scenes=2, noise=(0.0,), size=(96, 72), seed=3)
    out = write_dataset(nominal_rig(), spec, tmp_path / "old", shard=(0, 2), progress=False)
    meta = yaml.safe_load((out / "dataset.yaml").read_text())
    del meta["rigs"], meta["rig_of_scene"]
    (out / "dataset.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    path = out / "samples" / "0-000000.npz"
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files if k != "rig"}
    np.savez_compressed(path, **arrays)
    dataset = open_dataset(out)
    assert dataset.rig_names == ["rig"] and list(dataset.rigs) == ["rig"]
    assert dataset[0].rig == "rig" and dataset.rig.camera.size == (96, 72)
    write_dataset(nominal_rig(), spec, out, shard=(1, 2), progress=False)  # the other shard joins the old folder
    assert len(open_dataset(out)) == 2 and open_dataset(out).missing == 0
