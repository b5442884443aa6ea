"""Reading training samples of a ``dptpu-dataset/1`` folder (written by ``dptpu sim dataset``), without torch.

Folder layout::

    DIR/dataset.yaml          format: dptpu-dataset/1 (other keys describe how it was made)
    DIR/samples/*.npz         one sample each, read in sorted name order

Keys of a sample (arrays ``(H, W)``):

============== ========= ================================================================================
wrapped_high   float32   wrapped phase of the high frequency, radians in ``[0, 2pi)`` (noisy, few steps)
wrapped_low    float32   wrapped phase of the low frequency, radians in ``[0, 2pi)``
coarse_order   float32   the classical method's fringe order of the high frequency (may be wrong)
label_order    int16     the true fringe order of the high frequency (12-step, noise-free labels)
valid          bool      pixels that count
frequency_high scalar    periods across the projector
frequency_low  scalar    periods across the projector
method         str       mf | mw | nt
noise_sigma    scalar    camera noise, gray levels
scene_seed     scalar    seed of the scene
============== ========= ================================================================================

Non-finite values at pixels are made invalid (and set to 0) on reading.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

__all__ = ["DATASET_FORMAT", "Sample", "list_samples", "read_dataset_yaml", "read_sample"]

DATASET_FORMAT = "dptpu-dataset/1"
_ARRAY_KEYS = ("wrapped_high", "wrapped_low", "coarse_order", "label_order", "valid")
_SCALAR_KEYS = ("frequency_high", "frequency_low", "method")


@dataclass(frozen=True, eq=False)
class Sample:
    """One training sample; arrays ``(H, W)``; ``valid`` already excludes non-finite pixels."""

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
    name: str


def read_dataset_yaml(data_dir) -> dict:
    """The parsed ``dataset.yaml`` of ``data_dir``; ValueError unless its ``format`` is dptpu-dataset/1."""
    path = Path(data_dir) / "dataset.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no dataset.yaml (expected a {DATASET_FORMAT} folder from "
                                "'dptpu sim dataset')")
    document = yaml.safe_load(path.read_text()) or {}
    if not isinstance(document, dict) or document.get("format") != DATASET_FORMAT:
        found = document.get("format") if isinstance(document, dict) else type(document).__name__
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
    """Read and check one sample file (see the module docstring for its keys)."""
    path = Path(path)
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable .npz sample ({exc})") from None
    with archive:
        missing = [k for k in _ARRAY_KEYS + _SCALAR_KEYS if k not in archive.files]
        if missing:
            raise ValueError(f"{path}: missing keys {missing}; a {DATASET_FORMAT} sample has "
                             f"{list(_ARRAY_KEYS + _SCALAR_KEYS)}")
        arrays = {k: np.asarray(archive[k]) for k in _ARRAY_KEYS}
        shape = arrays["wrapped_high"].shape
        for key, array in arrays.items():
            if array.ndim != 2 or array.shape != shape:
                raise ValueError(f"{path}: {key} must be a (H, W) array like wrapped_high {shape}; "
                                 f"got shape {array.shape}")
        method = str(archive["method"])
        if method not in ("mf", "mw", "nt"):
            raise ValueError(f"{path}: method must be mf, mw or nt; got {method!r}")
        frequency_high = float(archive["frequency_high"])
        frequency_low = float(archive["frequency_low"])
        if not (frequency_high > 0 and frequency_low > 0):
            raise ValueError(f"{path}: frequency_high and frequency_low must be > 0; got "
                             f"{frequency_high:g}, {frequency_low:g}")
        noise_sigma = float(archive["noise_sigma"]) if "noise_sigma" in archive.files else float("nan")
        scene_seed = int(archive["scene_seed"]) if "scene_seed" in archive.files else -1
    finite = np.ones(shape, dtype=bool)
    for key in ("wrapped_high", "wrapped_low", "coarse_order"):
        finite &= np.isfinite(arrays[key])
    valid = arrays["valid"].astype(bool) & finite
    clean = {k: np.where(valid, arrays[k], 0).astype(np.float32)
             for k in ("wrapped_high", "wrapped_low", "coarse_order")}
    return Sample(label_order=np.where(valid, arrays["label_order"], 0).astype(np.int16), valid=valid,
                  frequency_high=frequency_high, frequency_low=frequency_low, method=method,
                  noise_sigma=noise_sigma, scene_seed=scene_seed, name=path.stem, **clean)
