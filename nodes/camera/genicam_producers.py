"""GenTL producers (``.cti`` files) that ship inside Python wheels, found without importing their packages.

A GenTL producer is the vendor's shared library that the GenICam transport layer loads to reach a
camera (Basler pylon's ``ProducerU3V.cti`` for the paper's acA640-750, for example). Two simulated
producers ship in wheels and let the camera node run and be tested without a camera:

=================  ==================  ==================================================================
producer           wheel               what it offers
=================  ==================  ==================================================================
``viky.cti``       ``genicam``         3 devices (serial ``0``, ``1``, ``2``: red, green, blue); 400x400,
                                       width and height 100..800; ``Mono8`` or ``RGBa8``; free-running
                                       only (no trigger, no exposure feature); ``AcquisitionFrameRate``
                                       1..200 Hz (20 by default); no buffer timestamps
``TLSimu.cti``     ``genicam2``        EMVA's reference simulator: 4 devices (``SN_InterfaceA_0`` mono,
                                       ``SN_InterfaceA_1`` colour, and the same on interface B);
                                       512x512, width and height 8..4096; ``Mono8`` .. ``Mono16`` and
                                       more; ``TriggerMode`` Off/On with ``TriggerSource`` Software and
                                       ``TriggerSoftware``; no exposure feature
=================  ==================  ==================================================================

``genicam2`` (an old wheel of the same binding, ``py3-none``) is only used for its ``TLSimu.cti``,
which the current ``genicam`` binding loads; its Python modules are never imported.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

__all__ = ["SHIPPED_PRODUCERS", "shipped_producer", "default_cti_paths", "split_cti_paths"]

#: ``{file name: package that ships it}``.
SHIPPED_PRODUCERS = {"viky.cti": "genicam", "TLSimu.cti": "genicam2"}


def shipped_producer(file_name: str) -> Path | None:
    """Path of a producer shipped in a wheel (``"viky.cti"``, ``"TLSimu.cti"``), or None when not installed."""
    package = SHIPPED_PRODUCERS.get(file_name)
    if package is None:
        raise ValueError(f"unknown shipped producer {file_name!r}; known: {', '.join(SHIPPED_PRODUCERS)}")
    spec = importlib.util.find_spec(package)  # locates the package without running its __init__
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        path = Path(folder) / file_name
        if path.is_file():
            return path
    return None


def default_cti_paths() -> list[Path]:
    """The producers to load when none is configured: ``viky.cti`` from the genicam wheel, if installed."""
    viky = shipped_producer("viky.cti")
    return [viky] if viky is not None else []


def split_cti_paths(text: str) -> list[Path]:
    """``"a.cti:b.cti"`` (``os.pathsep`` separated, as ``GENICAM_GENTL64_PATH``) -> paths; ``""`` -> defaults."""
    if not isinstance(text, str):
        raise ValueError(f"cti must be a string of .cti paths separated by {os.pathsep!r}; got {text!r}")
    paths = [Path(part) for part in text.split(os.pathsep) if part.strip()]
    for path in paths:
        if path.suffix != ".cti":
            raise ValueError(f"cti entries must be GenTL producer files ending in .cti; got {str(path)!r}")
    return paths or default_cti_paths()
