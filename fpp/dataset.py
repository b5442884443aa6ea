"""Reading the training datasets of format ``dptpu-dataset/1`` (docs/dataset.md is the specification).

The twin writes them (:mod:`dptpu.sim.dataset`, ``dptpu sim dataset``); training, evaluation and the experiments
read them here, as :class:`Sample` objects. Folder layout::

    DIR/dataset.yaml                    format: dptpu-dataset/1 (other keys describe how it was made)
    DIR/rig.yaml                        the rig rendered (dptpu-rig/1); several rigs: DIR/rig-<name>.yaml each
    DIR/samples/*.npz                   one sample each; the twin names them <shard>-<index:06d>.npz

Two ways in: :func:`list_samples` (every ``samples/*.npz`` in name order, whatever the names: what training and
evaluation read, also from folders not written by the twin) and :func:`open_dataset` (a lazy sequence in global
index order, for folders named by the twin, with its rigs).

Keys of a sample file (arrays ``(H, W)``; the first eight are required):

============== ========= ================================================================================
wrapped_high   float32   wrapped phase of the high frequency, radians in ``[0, 2pi)`` (noisy, few steps)
wrapped_low    float32   wrapped phase of the low frequency, radians in ``[0, 2pi)``
coarse_order   float32   the classical method's fringe order of the high frequency (may be wrong)
label_order    int16     the true fringe order of the high frequency (12-step, noise-free labels)
valid          bool      pixels that count
frequency_high scalar    periods across the projector
frequency_low  scalar    periods across the projector
method         str       mf | mw | nt
noise_sigma    scalar    camera noise, gray levels (NaN when absent)
scene_seed     scalar    seed of the scene (-1 when absent)
label_rejected scalar    pixels dropped only because the 12-step label disagreed with the ray cast (-1 when absent)
rig            str       name of the rig that rendered the sample (None when absent: older samples)
============== ========= ================================================================================

Non-finite values at pixels are made invalid (and set to 0) on reading.
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from .calibration import Rig, load_rig
from .methods import TWO_FREQUENCY_METHODS

__all__ = [
    "DATASET_FORMAT",
    "SAMPLE_ARRAYS",
    "SAMPLE_RIG",
    "SAMPLE_SCALARS",
    "Dataset",
    "Sample",
    "list_samples",
    "open_dataset",
    "read_dataset_yaml",
    "read_sample",
    "sample_name",
]

DATASET_FORMAT = "dptpu-dataset/1"
#: Array keys of a sample file, each (H, W).
SAMPLE_ARRAYS = ("wrapped_high", "wrapped_low", "coarse_order", "label_order", "valid")
#: Scalar keys of a sample file as the twin writes it (the first three are required).
SAMPLE_SCALARS = ("frequency_high", "frequency_low", "method", "noise_sigma", "scene_seed", "label_rejected")
#: Optional scalar key: the name of the sample's rig (written since multi-rig datasets; older samples lack it).
SAMPLE_RIG = "rig"
_REQUIRED = SAMPLE_ARRAYS + SAMPLE_SCALARS[:3]
_NAME = re.compile(r"^(\d+)-(\d{6,})\.npz$")


@dataclass(frozen=True, eq=False)
class Sample:
    """One sample; arrays ``(H, W)``; ``valid`` already excludes non-finite pixels, where the arrays hold 0."""

    wrapped_high: np.ndarray  # float32, radians
    wrapped_low: np.ndarray  # float32, radians
    coarse_order: np.ndarray  # float32, fringe orders
    label_order: np.ndarray  # int16, fringe orders
    valid: np.ndarray  # bool
    frequency_high: float
    frequency_low: float
    method: str
    noise_sigma: float
    scene_seed: int
    name: str  # the file's stem
    label_rejected: int = -1
    rig: str | None = None


def sample_name(shard: int, index: int) -> str:
    """The twin's name of sample ``index`` written by shard ``shard``: ``<shard>-<index:06d>.npz``."""
    return f"{int(shard)}-{int(index):06d}.npz"


def read_dataset_yaml(data_dir) -> dict:
    """The parsed ``dataset.yaml`` of ``data_dir``.

    Raises
    ------
    FileNotFoundError
        No ``dataset.yaml``.
    ValueError
        It is not valid YAML, or its ``format`` is not ``dptpu-dataset/1``.
    """
    path = Path(data_dir) / "dataset.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file (no dataset.yaml: not a {DATASET_FORMAT} folder from "
                                "'dptpu sim dataset')")
    try:
        document = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(document, dict) or document.get("format") != DATASET_FORMAT:
        found = document.get("format") if isinstance(document, dict) else document
        raise ValueError(f"{path}: format must be {DATASET_FORMAT!r}; got {found!r}")
    return document


def list_samples(data_dir) -> list[Path]:
    """Sorted ``samples/*.npz`` of a dataset folder (checks ``dataset.yaml``); ValueError if there are none."""
    read_dataset_yaml(data_dir)
    paths = sorted((Path(data_dir) / "samples").glob("*.npz"))
    if not paths:
        raise ValueError(f"{Path(data_dir) / 'samples'}: no .npz samples")
    return paths


def read_sample(path) -> Sample:
    """Read and check one sample file (see the module docstring for its keys).

    Raises
    ------
    ValueError
        Not a readable ``.npz``, a required key missing, arrays of different shapes, an unknown method or a
        frequency <= 0.
    """
    path = Path(path)
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable .npz sample ({exc})") from None
    with archive:
        missing = [k for k in _REQUIRED if k not in archive.files]
        if missing:
            raise ValueError(f"{path}: missing keys {missing}; a {DATASET_FORMAT} sample has {list(_REQUIRED)}")
        arrays = {k: np.asarray(archive[k]) for k in SAMPLE_ARRAYS}
        shape = arrays["wrapped_high"].shape
        for key, array in arrays.items():
            if array.ndim != 2 or array.shape != shape:
                raise ValueError(f"{path}: {key} must be a (H, W) array like wrapped_high {shape}; "
                                 f"got shape {array.shape}")
        method = str(archive["method"])
        if method not in TWO_FREQUENCY_METHODS:
            raise ValueError(f"{path}: method must be mf, mw or nt; got {method!r}")
        frequency_high = float(archive["frequency_high"])
        frequency_low = float(archive["frequency_low"])
        if not (frequency_high > 0 and frequency_low > 0):
            raise ValueError(f"{path}: frequency_high and frequency_low must be > 0; got "
                             f"{frequency_high:g}, {frequency_low:g}")
        files = archive.files
        noise_sigma = float(archive["noise_sigma"]) if "noise_sigma" in files else float("nan")
        scene_seed = int(archive["scene_seed"]) if "scene_seed" in files else -1
        label_rejected = int(archive["label_rejected"]) if "label_rejected" in files else -1
        rig = str(archive[SAMPLE_RIG]) if SAMPLE_RIG in files else None
    finite = np.ones(shape, dtype=bool)
    for key in ("wrapped_high", "wrapped_low", "coarse_order"):
        finite &= np.isfinite(arrays[key])
    valid = arrays["valid"].astype(bool) & finite
    clean = {k: np.where(valid, arrays[k], 0).astype(np.float32)
             for k in ("wrapped_high", "wrapped_low", "coarse_order")}
    return Sample(label_order=np.where(valid, arrays["label_order"], 0).astype(np.int16), valid=valid,
                  frequency_high=frequency_high, frequency_low=frequency_low, method=method,
                  noise_sigma=noise_sigma, scene_seed=scene_seed, name=path.stem, label_rejected=label_rejected,
                  rig=rig, **clean)


@dataclass(frozen=True, eq=False)
class Dataset(Sequence):
    """A ``dptpu-dataset/1`` folder as a lazy sequence: ``len(dataset)``, ``dataset[i]`` reads one :class:`Sample`.

    Attributes
    ----------
    root : Path
    meta : dict
        The parsed ``dataset.yaml``.
    paths : tuple of Path
        Sample files in global-index order.
    """

    root: Path
    meta: dict
    paths: tuple = field(default_factory=tuple)

    def __len__(self) -> int:
        return len(self.paths)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        if not isinstance(index, (int, np.integer)):
            raise TypeError(f"dataset indices must be integers or slices; got {type(index).__name__}")
        if not -len(self) <= index < len(self):
            raise IndexError(f"sample {index} out of range for {len(self)} samples")
        sample = read_sample(self.paths[index])
        if sample.rig is None:
            sample = replace(sample, rig=self.rig_names[0])  # a one-rig folder from before samples named their rig
        return sample

    @property
    def missing(self) -> int:
        """Samples ``dataset.yaml`` announces that are not (yet) on disk (e.g. shards still running)."""
        return int(self.meta.get("count", len(self))) - len(self)

    @property
    def rig(self) -> Rig:
        """The (first) rig the samples were rendered with."""
        return load_rig(self.root / str(self.meta.get("rig", "rig.yaml")))

    @property
    def rig_names(self) -> list[str]:
        """Names of the rigs in ``dataset.yaml`` order; ``["rig"]`` for folders that do not list them."""
        return [str(entry["name"]) for entry in self._rig_entries()]

    @property
    def rigs(self) -> dict:
        """``{name: Rig}`` of every rig of the dataset, in ``dataset.yaml`` order."""
        return {str(e["name"]): load_rig(self.root / str(e["file"])) for e in self._rig_entries()}

    def _rig_entries(self) -> list[dict]:
        entries = self.meta.get("rigs")
        if entries is None:
            return [{"name": "rig", "file": str(self.meta.get("rig", "rig.yaml"))}]
        if not isinstance(entries, list) or not all(isinstance(e, dict) and "name" in e and "file" in e
                                                    for e in entries) or not entries:
            raise ValueError(f"{self.root / 'dataset.yaml'}: rigs must be a list of {{name, file}} entries; "
                             f"got {entries!r}")
        return entries


def open_dataset(path) -> Dataset:
    """Open a dataset folder written by the twin for reading (no sample is read until indexed).

    Raises
    ------
    FileNotFoundError
        No ``dataset.yaml``.
    ValueError
        ``dataset.yaml`` is not ``dptpu-dataset/1``, or ``samples/`` holds files not named
        ``<shard>-<index:06d>.npz`` or two files of the same index.
    """
    root = Path(path)
    meta = read_dataset_yaml(root)
    indexed: dict[int, Path] = {}
    for file in sorted((root / "samples").glob("*.npz")) if (root / "samples").is_dir() else []:
        match = _NAME.match(file.name)
        if not match:
            raise ValueError(f"{file}: sample files must be named <shard>-<index:06d>.npz")
        sample_index = int(match.group(2))
        if sample_index in indexed:
            raise ValueError(f"{file}: index {sample_index} is also in {indexed[sample_index].name} "
                             f"(shards of two different runs in one folder?)")
        indexed[sample_index] = file
    return Dataset(root=root, meta=meta, paths=tuple(indexed[i] for i in sorted(indexed)))
