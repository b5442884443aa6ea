"""How ``python -m dptpu.nodes.NAME`` starts a node: its package exports on first use, its ``__main__`` quiet on
Ctrl-C while it still imports.

A node's module imports for a while (numpy, ZeroMQ, OpenCV, onnxruntime: seconds on a loaded host). A SIGINT in
that time (Ctrl-C, or ``dptpu launch`` stopping the graph while a node starts) raised ``KeyboardInterrupt`` inside
an import, which Python printed as a traceback. The node packages therefore import their ``node`` module on first
use (PEP 562's module ``__getattr__``: :func:`node_exports`), so that ``python -m`` reaches the package's
``__main__``, which imports it through :func:`run_node_module` and ends a start-up interrupted there with exit code
0 and no output, as :func:`dptpu.nodes.node_main.run_node` does for one interrupted while the node is built.

This module imports nothing but the standard library: it runs before the heavy imports.
"""
from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterable
from typing import Any, NoReturn

__all__ = ["node_exports", "run_node_module"]


def node_exports(package: str, names: Iterable[str]) -> Callable[[str], Any]:
    """A package's module ``__getattr__`` (PEP 562) that imports ``names`` from ``package.node`` on first use.

    Parameters
    ----------
    package : str
        The node package's ``__name__``, e.g. ``dptpu.nodes.cloud``.
    names : iterable of str
        What the package exports from its ``node`` module (its ``__all__``).
    """
    exported = frozenset(names)

    def __getattr__(name: str) -> Any:
        if name not in exported:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.node"), name)

    return __getattr__


def run_node_module(package: str) -> NoReturn:
    """``python -m PACKAGE``: import ``PACKAGE.node`` and exit with what its ``main()`` returns.

    Ctrl-C (SIGINT) while the module still imports exits with code 0 and prints nothing, as a stop during start-up.
    """
    try:
        main = importlib.import_module(f"{package}.node").main
    except KeyboardInterrupt:
        sys.exit(0)
    sys.exit(main())
