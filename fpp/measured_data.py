"""Where the real measured data lives: ``$DPTPU_DATA``, else ``../shared/data`` beside the checkout.

The real data sets (``dptpu-sphere/``, ``cfpe/``) are never copied into the repository; the twin's validation,
the CLI and the tests find them here.
"""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["shared_data_dir"]


def shared_data_dir() -> Path:
    """The folder holding ``dptpu-sphere/`` and ``cfpe/`` (it may not exist: callers say so)."""
    if os.environ.get("DPTPU_DATA"):
        return Path(os.environ["DPTPU_DATA"])
    for base in (Path.cwd(), Path(__file__).resolve().parents[1]):
        candidate = base.parent / "shared" / "data"
        if candidate.is_dir():
            return candidate
    return Path.cwd().parent / "shared" / "data"
