"""MATLAB ``.mat`` files (the Bouguet toolbox's calibrations, the DP-TPU sphere data's phase maps), read once.

One reader with one error for every caller: a missing file is ``FileNotFoundError``, a damaged or foreign one a
``ValueError`` that names the file, never scipy's own exception types.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any


def read_mat(path, *, what: str = "file") -> dict[str, Any]:
    """The variables of the ``.mat`` file ``path`` (``scipy.io.loadmat``'s dictionary).

    Parameters
    ----------
    path : path-like
        A MATLAB v4-v7.2 ``.mat`` file.
    what : str
        What the file holds, for the missing-file message (``"calibration file"``, ``"phase file"``).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        ``path`` is not a readable ``.mat`` file.
    """
    from scipy.io import loadmat  # scipy.io: heavy to import, and only .mat files need it

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such {what}")
    try:
        return loadmat(str(path))
    except Exception as exc:  # noqa: BLE001 -- scipy raises several unrelated types for a damaged or foreign file
        raise ValueError(f"{path}: not a readable MATLAB .mat file ({exc})") from None
