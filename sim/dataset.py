"""Writing the twin's training datasets, format ``dptpu-dataset/1`` (sharded, in processes).

A dataset is ``scenes`` random scenes (:func:`dptpu.sim.scenes.random_scene`) times every combination of high
frequency, method and noise level; each combination of each scene is one sample file
(:mod:`dptpu.sim.dataset_samples` computes them). docs/dataset.md is the format's specification::

    DIR/dataset.yaml                    format: dptpu-dataset/1, how the set was made, count, shards, rigs
    DIR/rig.yaml                        the rig rendered (dptpu-rig/1, camera at the dataset's size)
    DIR/rig-<name>.yaml                 several rigs: one file per rig instead of rig.yaml
    DIR/samples/<shard>-<index>.npz     one sample: <shard> = the shard that wrote it, <index> = global index

Several rigs (e.g. ``nominal`` and ``wide``, so that the labels cover the whole fringe-order range) split the
scenes: scene ``i`` is rendered with rig ``i % len(rigs)``, and each sample records its rig's name (``rig``).

Sample ``index = scene_index * per_scene + combination`` with combinations ordered frequency, method, noise
(innermost); scene ``i`` has the seed ``scene_seed(seed, i)``. Shard ``I`` of ``N`` renders the scenes
``i % N == I``, so the shards' samples together are exactly the unsharded set (same indices, same arrays); only
the ``<shard>`` prefix of the file names differs. Shards may write into one folder (each writes the same
``dataset.yaml``) or into separate folders whose ``samples/`` are merged later. They are read through
:mod:`dptpu.fpp.dataset` (:func:`~dptpu.fpp.dataset.open_dataset`, :func:`~dptpu.fpp.dataset.read_sample`).
"""
from __future__ import annotations

import os
import re
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from dptpu.fpp.calibration import Rig, load_rig, save_rig
from dptpu.fpp.dataset import DATASET_FORMAT, SAMPLE_RIG, sample_name

from .dataset_samples import METHODS, check_combination, low_frequency, scene_samples
from .rig import resize_camera
from .scenes import random_scene

__all__ = [
    "DatasetSpec",
    "parse_shard",
    "scene_rig",
    "scene_seed",
    "write_dataset",
]

_RIG_NAME = re.compile(r"^[A-Za-z0-9_.+-]+$")


@dataclass(frozen=True)
class DatasetSpec:
    """How a dataset is made (the ``dataset.yaml`` keys besides format, rig, count, shards).

    Attributes
    ----------
    frequencies : tuple of float
        High frequencies, periods across the projector width (the paper's S4: 32, 48, 64, 80).
    methods : tuple of str
        ``mf``, ``mw``, ``nt`` (low frequencies 1, ``f_h - 1``, 10.9).
    scenes : int
        Number of random scenes (>= 1).
    input_steps, label_steps : int
        Phase steps of the noisy inputs and of the labels (>= 3 each; the paper: 3 and 12).
    noise : tuple of float
        Camera noise levels, gray levels (>= 0); every level is rendered for every scene (the paper's 1 and 2
        sigma: 1.5693, 3.1386).
    size : (int, int)
        Camera ``(width, height)`` of the samples.
    seed : int
        Root of the scene seeds.
    meshes : str or None
        Folder of user meshes for the random scenes.
    """

    frequencies: tuple = (32.0, 48.0, 64.0, 80.0)
    methods: tuple = METHODS
    scenes: int = 1
    input_steps: int = 3
    label_steps: int = 12
    noise: tuple = (1.5693,)
    size: tuple = (640, 480)
    seed: int = 0
    meshes: str | None = None

    def __post_init__(self):
        frequencies = tuple(float(f) for f in self.frequencies)
        if not frequencies or len(set(frequencies)) != len(frequencies):
            raise ValueError(f"--frequencies must list distinct frequencies; got {list(self.frequencies)}")
        methods = tuple(str(m) for m in self.methods)
        unknown = [m for m in methods if m not in METHODS]
        if not methods or unknown or len(set(methods)) != len(methods):
            raise ValueError(f"--methods must list distinct methods among {', '.join(METHODS)}; got {list(methods)}")
        noise = tuple(float(s) for s in self.noise)
        if not noise or any(not np.isfinite(s) or s < 0 for s in noise):
            raise ValueError(f"--noise must list one or more sigmas >= 0 (gray levels); got {list(self.noise)}")
        for name in ("input_steps", "label_steps"):
            if int(getattr(self, name)) < 3:
                raise ValueError(f"--{name.replace('_', '-')} must be >= 3; got {getattr(self, name)}")
        if int(self.scenes) < 1:
            raise ValueError(f"--scenes must be >= 1; got {self.scenes}")
        size = tuple(int(v) for v in self.size)
        if len(size) != 2 or min(size) < 8:
            raise ValueError(f"--size must be WIDTHxHEIGHT >= 8x8; got {self.size}")
        for key, value in (("frequencies", frequencies), ("methods", methods), ("noise", noise), ("size", size),
                           ("scenes", int(self.scenes)), ("input_steps", int(self.input_steps)),
                           ("label_steps", int(self.label_steps)), ("seed", int(self.seed))):
            object.__setattr__(self, key, value)

    @property
    def combinations(self) -> list[tuple[float, str, float]]:
        """``(f_h, method, sigma)`` of each sample of a scene, in file order."""
        return [(f, m, s) for f in self.frequencies for m in self.methods for s in self.noise]

    @property
    def per_scene(self) -> int:
        return len(self.combinations)

    @property
    def count(self) -> int:
        """Samples in the whole (unsharded) dataset."""
        return self.scenes * self.per_scene


def scene_seed(seed: int, scene_index: int) -> int:
    """Seed of scene ``scene_index`` of a dataset of seed ``seed`` (independent streams, no overlap between seeds)."""
    return int(np.random.SeedSequence([int(seed), int(scene_index)]).generate_state(1)[0])


def parse_shard(text) -> tuple[int, int]:
    """``"I/N"`` -> ``(I, N)`` with ``0 <= I < N``."""
    match = re.fullmatch(r"\s*(\d+)\s*/\s*(\d+)\s*", str(text))
    if not match or not int(match.group(1)) < int(match.group(2)):
        raise ValueError(f"--shard must be I/N with 0 <= I < N (e.g. 0/4); got {text!r}")
    return int(match.group(1)), int(match.group(2))


def scene_rig(scene_index: int, rig_count: int) -> int:
    """Index of the rig that renders scene ``scene_index`` of a dataset of ``rig_count`` rigs (round robin)."""
    return int(scene_index) % int(rig_count)


def _named_rigs(rig) -> list[tuple[str, Rig]]:
    """``[(name, Rig), ...]`` from a Rig, a mapping name -> Rig or a sequence of Rigs or (name, Rig) pairs."""
    if isinstance(rig, Rig):
        return [("rig", rig)]
    items = list(rig.items()) if isinstance(rig, dict) else list(rig)
    named = []
    for k, item in enumerate(items):
        name, value = item if isinstance(item, tuple) else (f"rig{k}", item)
        if not isinstance(value, Rig):
            raise TypeError(f"rigs must be Rig objects; rig {k} ({name!r}) is a {type(value).__name__}")
        if not _RIG_NAME.match(str(name)):
            raise ValueError(f"rig names must be letters, digits, '_', '.', '+' or '-'; got {name!r}")
        named.append((str(name), value))
    if not named:
        raise ValueError("a dataset needs at least one rig")
    names = [n for n, _ in named]
    if len(set(names)) != len(names):
        raise ValueError(f"rig names must be distinct; got {names}")
    return named


# --------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------

def _rig_files(names: list[str]) -> list[str]:
    """``rig.yaml`` for one rig (the original layout), ``rig-<name>.yaml`` for several."""
    return ["rig.yaml"] if len(names) == 1 else [f"rig-{name}.yaml" for name in names]


def _document(spec: DatasetSpec, shards: int, names: list[str]) -> dict:
    low = {m: {f"{f:g}": low_frequency(m, f) for f in spec.frequencies} for m in spec.methods}
    files = _rig_files(names)
    rigs = [{"name": name, "file": file, "scenes": len(range(k, spec.scenes, len(names)))}
            for k, (name, file) in enumerate(zip(names, files))]
    return {"format": DATASET_FORMAT, "rig": files[0], "rigs": rigs,
            "rig_of_scene": "rigs[scene_index % len(rigs)]", "frequencies": list(spec.frequencies),
            "methods": list(spec.methods), "low_frequencies": low, "input_steps": spec.input_steps,
            "label_steps": spec.label_steps, "noise": list(spec.noise), "size": list(spec.size), "seed": spec.seed,
            "scenes": spec.scenes, "meshes": spec.meshes, "count": spec.count, "per_scene": spec.per_scene,
            "shards": shards, "fringe_axis": "x", "samples": "samples/<shard>-<index:06d>.npz",
            "order": "index = scene_index * per_scene + combination; combinations: frequency, method, noise"}


_SAME_KEYS = ("frequencies", "methods", "input_steps", "label_steps", "noise", "size", "seed", "scenes", "meshes",
              "shards", "rigs")


def _write_text_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _prepare_folder(out: Path, spec: DatasetSpec, rigs: list[tuple[str, Rig]], shards: int) -> list[Path]:
    """Create the folder, write the rig files and ``dataset.yaml``; returns the rig files in rig order."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "samples").mkdir(exist_ok=True)
    names = [name for name, _ in rigs]
    document = _document(spec, shards, names)
    existing = out / "dataset.yaml"
    if existing.is_file():
        try:
            old = yaml.safe_load(existing.read_text()) or {}
        except yaml.YAMLError:
            old = {}
        if old.get("format") != DATASET_FORMAT:
            raise ValueError(f"{existing}: exists and is not a {DATASET_FORMAT} file; choose another --out")
        for key in _SAME_KEYS:
            if key == "rigs" and "rigs" not in old and len(names) == 1:
                continue  # a one-rig folder written before datasets recorded their rigs
            if old.get(key) != document[key]:
                raise ValueError(f"{existing}: {key} is {old.get(key)!r} but this run has {document[key]!r}; one "
                                 f"folder holds one dataset (choose another --out)")
    paths = []
    for (_, rig), file in zip(rigs, _rig_files(names)):
        tmp = out / f".{file}.{os.getpid()}.tmp.yaml"
        save_rig(rig, tmp)
        os.replace(tmp, out / file)
        paths.append(out / file)
    _write_text_atomic(existing, yaml.safe_dump(document, sort_keys=False, default_flow_style=None))
    return paths


def _save_sample(path: Path, sample: dict) -> None:
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    with open(tmp, "wb") as handle:
        np.savez_compressed(handle, **sample)
    os.replace(tmp, path)


def _render_scene(job) -> int:
    """Worker: render scene ``scene_index`` and write its samples; returns the number written."""
    rig_path, rig_name, spec_dict, scene_index, shard, samples_dir = job

    spec = DatasetSpec(**spec_dict)
    rig = load_rig(rig_path)
    seed = scene_seed(spec.seed, scene_index)
    scene = random_scene(rig, seed, meshes_dir=spec.meshes)
    samples = scene_samples(rig, scene, scene_seed=seed, frequencies=spec.frequencies, methods=spec.methods,
                            noise_sigmas=spec.noise, input_steps=spec.input_steps, label_steps=spec.label_steps)
    for j, sample in enumerate(samples):
        sample[SAMPLE_RIG] = np.str_(rig_name)
        _save_sample(Path(samples_dir) / sample_name(shard, scene_index * spec.per_scene + j), sample)
    return len(samples)


def write_dataset(rig, spec: DatasetSpec, out_dir, *, shard=(0, 1), workers: int = 1,
                  progress: bool = True) -> Path:
    """Render the samples of shard ``shard`` of the dataset ``spec`` into ``out_dir``.

    Parameters
    ----------
    rig : Rig, dict of str to Rig, or sequence of Rig or of (name, Rig)
        The twin's rig or rigs; cameras are resized to ``spec.size`` (``K`` scaled). One rig is written as
        ``rig.yaml`` (its name ``"rig"`` unless given); several as ``rig-<name>.yaml`` (default names ``rig0``,
        ``rig1``, ...), and scene ``i`` is rendered with rig ``i % len(rigs)`` (:func:`scene_rig`).
    spec : DatasetSpec
    out_dir : path-like
        The dataset folder (created). A folder holding another dataset (a different ``dataset.yaml``) is refused;
        samples already written are kept and not rendered again (a stopped run resumes).
    shard : (int, int)
        ``(I, N)``: render the scenes ``i`` with ``i % N == I``.
    workers : int
        Processes rendering scenes in parallel (1 = in this process).
    progress : bool
        Draw a progress bar (tqdm) on stderr.

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    ValueError
        A frequency a method cannot unwrap (e.g. an ambiguous NT pair), a bad shard or worker count, or a folder
        holding another dataset.
    """
    rigs = _named_rigs(rig)
    index, total = shard
    if not (0 <= int(index) < int(total)):
        raise ValueError(f"shard must be (I, N) with 0 <= I < N; got {shard}")
    if int(workers) < 1:
        raise ValueError(f"--workers must be >= 1; got {workers}")
    for _, one in rigs:
        for f in spec.frequencies:
            for method in spec.methods:
                check_combination(method, f, one.projector.size[0])
    if spec.meshes is not None and not Path(spec.meshes).is_dir():
        raise FileNotFoundError(f"{spec.meshes}: no such meshes folder")
    rigs = [(name, resize_camera(one, spec.size) if tuple(one.camera.size) != tuple(spec.size) else one)
            for name, one in rigs]
    out = Path(out_dir)
    rig_paths = _prepare_folder(out, spec, rigs, int(total))
    samples_dir = out / "samples"
    spec_dict = asdict(spec)
    jobs = []
    for scene_index in range(int(index), spec.scenes, int(total)):
        names = [samples_dir / sample_name(index, scene_index * spec.per_scene + j) for j in range(spec.per_scene)]
        if not all(p.is_file() for p in names):
            k = scene_rig(scene_index, len(rigs))
            jobs.append((str(rig_paths[k]), rigs[k][0], spec_dict, scene_index, int(index), str(samples_dir)))
    with tqdm(total=len(jobs), desc="dataset", unit="scene", disable=not progress, file=sys.stderr) as bar:
        if int(workers) == 1 or len(jobs) <= 1:
            for job in jobs:
                _render_scene(job)
                bar.update()
        else:
            with ProcessPoolExecutor(max_workers=int(workers), mp_context=get_context("spawn")) as pool:
                for _ in pool.map(_render_scene, jobs):
                    bar.update()
    return out
