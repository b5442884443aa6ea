"""Can ``python -m MODULE`` run? Found by path search only: no module or package code is executed."""
from __future__ import annotations

import difflib
import importlib.util
import pkgutil
import re
from collections.abc import Sequence
from importlib.machinery import ModuleSpec, PathFinder

__all__ = ["module_problem"]

_DOTTED_NAME = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")


def _find_top_level(name: str, search_path: Sequence[str]) -> ModuleSpec | None:
    spec = PathFinder.find_spec(name, list(search_path))
    if spec is None:  # an installed editable package, a builtin or a frozen module: the import system knows
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            spec = None
    return spec


def _sibling_hint(missing: str, locations: Sequence[str]) -> str:
    names = [info.name for info in pkgutil.iter_modules(list(locations))]
    close = difflib.get_close_matches(missing, names, n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def module_problem(module: str, search_path: Sequence[str]) -> str | None:
    """Why ``python -m module`` would fail to find ``module``, or ``None`` when it would find it.

    Each dotted component is looked up in the locations of its parent package with
    :class:`importlib.machinery.PathFinder` (the top level also through :func:`importlib.util.find_spec`,
    which knows editable installs), so no package ``__init__`` runs. A package must have ``__main__``.

    Parameters
    ----------
    module : str
        Dotted module name, e.g. ``dptpu.nodes.phase``.
    search_path : sequence of str
        Directories searched for the top-level package, first to last (the child's ``sys.path``).

    Returns
    -------
    str or None
        A sentence naming the missing piece (with a close match when there is one), or ``None``.
    """
    if not isinstance(module, str) or not _DOTTED_NAME.fullmatch(module):
        return f"{module!r} is not a dotted Python module name (like dptpu.nodes.phase)"
    parts = module.split(".")
    spec = _find_top_level(parts[0], search_path)
    if spec is None:
        return f"no module named {parts[0]!r} (searched the working directory, PYTHONPATH and sys.path)"
    for index in range(1, len(parts)):
        parent, fullname = ".".join(parts[:index]), ".".join(parts[:index + 1])
        locations = spec.submodule_search_locations
        if locations is None:
            return f"no module named {fullname!r}: {parent!r} is a module, not a package"
        spec = PathFinder.find_spec(fullname, list(locations))
        if spec is None:
            return f"no module named {fullname!r}{_sibling_hint(parts[index], locations)}"
    if spec.submodule_search_locations is not None:
        if PathFinder.find_spec(f"{module}.__main__", list(spec.submodule_search_locations)) is None:
            return f"{module!r} is a package without a __main__ module, so python -m cannot run it"
    return None
