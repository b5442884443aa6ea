"""``dptpu bench NAME [ARGS...]``: run ``benchmarks/NAME_bench.py`` of the source tree with its own options.

Every ``benchmarks/*_bench.py`` file is a target (``fpp``, ``transport``, ``twin``, ``pipeline``, ``bridge``,
...; ``dptpu bench --help`` lists the ones found). The command parses nothing but the name: ``ARGS`` go
unchanged to the module's own ``main(argv)`` (its own argparse, so ``dptpu bench transport --help`` prints that
module's options, and ``dptpu bench NAME ARGS`` is the same as ``python benchmarks/NAME_bench.py ARGS``). A
module without ``main`` is run through its ``build_parser()`` (or ``add_arguments(parser)``) and ``run(args)``.

The benchmark code is not part of the installed package, so this command loads it from the source tree (the
``benchmarks`` folder next to the ``dptpu`` package folder) and says so when it is missing (``dptpu``
installed from a wheel instead of a source checkout). What is measured, and against what, is written in each
file's docstring and in ``docs/benchmarks.md``.
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

#: File name suffix of a benchmark module: ``benchmarks/<name>_bench.py`` is target ``<name>``.
SUFFIX = "_bench.py"
#: Name under which ``benchmarks/fpp_bench.py`` is registered in ``sys.modules`` once loaded.
MODULE_NAME = "dptpu_benchmarks_fpp_bench"
#: The same for ``benchmarks/transport_bench.py`` (``dptpu bench transport``).
TRANSPORT_MODULE_NAME = "dptpu_benchmarks_transport_bench"
#: The same for ``benchmarks/twin_bench.py`` (``dptpu bench twin``).
TWIN_MODULE_NAME = "dptpu_benchmarks_twin_bench"
#: The same for ``benchmarks/pipeline_bench.py`` (``dptpu bench pipeline``).
PIPELINE_MODULE_NAME = "dptpu_benchmarks_pipeline_bench"


def benchmarks_dir() -> Path:
    """The source tree's ``benchmarks`` folder: ``<repo>/benchmarks``, beside ``cli/``."""
    return Path(__file__).resolve().parents[1] / "benchmarks"


def module_name(target: str) -> str:
    """The ``sys.modules`` name of target ``target``'s module: ``dptpu_benchmarks_<target>_bench``."""
    return f"dptpu_benchmarks_{target}_bench"


def targets() -> dict[str, str]:
    """``{name: first docstring line}`` of every ``benchmarks/*_bench.py`` (empty without a source tree).

    Only each file's first line is read (no import), so listing the targets stays cheap.
    """
    folder = benchmarks_dir()
    found = {}
    for path in sorted(folder.glob(f"*{SUFFIX}")) if folder.is_dir() else ():
        try:
            with path.open(encoding="utf-8") as handle:
                first = handle.readline().strip()
        except OSError:
            first = ""
        found[path.name[:-len(SUFFIX)]] = first.strip('"').strip("'").strip()
    return found


def load_fpp_bench():
    """Import ``benchmarks/fpp_bench.py`` as a module (once per process); see :func:`load_bench`."""
    return load_bench("fpp_bench.py", MODULE_NAME)


def load_transport_bench():
    """Import ``benchmarks/transport_bench.py`` as a module (once per process); see :func:`load_bench`."""
    return load_bench("transport_bench.py", TRANSPORT_MODULE_NAME)


def load_target(target: str):
    """Import ``benchmarks/<target>_bench.py`` (once per process); ValueError for a malformed name."""
    if not target or not target.replace("_", "").isalnum():
        raise ValueError(f"benchmark name must be letters, digits and '_' (benchmarks/NAME{SUFFIX}); got {target!r}")
    return load_bench(f"{target}{SUFFIX}", module_name(target))


def load_bench(file_name: str, module_name: str):
    """Import ``benchmarks/<file_name>`` as module ``module_name`` (once per process).

    Raises
    ------
    FileNotFoundError
        When the file is absent, naming the path looked at, the targets that exist, and what to do.
    """
    path = benchmarks_dir() / file_name
    loaded = sys.modules.get(module_name)
    if loaded is not None and Path(getattr(loaded, "__file__", "")) == path:
        return loaded
    if not path.is_file():
        known = ", ".join(targets()) or "none"
        raise FileNotFoundError(
            f"benchmark code not found at {path} (targets found: {known}): `dptpu bench` runs from a source "
            "checkout of dptpu (the benchmarks/ folder is not installed with the package); clone the repository "
            f"and `pip install -e .` it, or run `python benchmarks/{file_name}` there"
        )
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"{path}: not loadable as a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # before exec: dataclasses and pickling look modules up by name
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[module_name]
        raise
    return module


def run_module(module, target: str, argv: list[str]) -> int:
    """Run a loaded benchmark module with command-line ``argv``; its exit code.

    ``module.main(argv)`` when it has one; else ``module.run(args)`` with ``args`` parsed by
    ``module.build_parser()`` or by a parser that ``module.add_arguments`` fills.
    """
    main = getattr(module, "main", None)
    if callable(main):
        return int(main(list(argv)) or 0)
    if callable(getattr(module, "build_parser", None)):
        parser = module.build_parser()
        parser.prog = f"dptpu bench {target}"
    else:
        doc = (module.__doc__ or "").split("\n\n")[0]
        parser = argparse.ArgumentParser(prog=f"dptpu bench {target}", description=doc)
        if callable(getattr(module, "add_arguments", None)):
            module.add_arguments(parser)
    if not callable(getattr(module, "run", None)):
        raise ValueError(f"benchmark module {module.__file__} has neither main(argv) nor run(args)")
    return int(module.run(parser.parse_args(list(argv))) or 0)


def register(subparsers) -> None:
    found = targets()
    listing = "\n".join(f"  {name:<10} {line}" for name, line in found.items()) or "  (no benchmarks/ folder found)"
    parser = subparsers.add_parser(
        "bench", help="benchmarks against reference implementations (not tests)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Runs benchmarks/NAME_bench.py of the source tree; ARGS go to that module's own options "
                    "(`dptpu bench NAME --help` lists them).",
        epilog=f"benchmarks (NAME):\n{listing}")
    parser.add_argument("target", metavar="NAME", help=f"benchmark: one of {', '.join(found) or '(none found)'}")
    parser.add_argument("bench_args", metavar="ARGS", nargs=argparse.REMAINDER,
                        help="options of that benchmark, passed unchanged")
    parser.set_defaults(func=run)


def run(args) -> int:
    """``dptpu bench NAME ARGS``: load the module and hand it ``ARGS``; its exit code.

    A ``RuntimeError`` of the benchmark (a missing optional library, a benchmark process that failed)
    becomes one line on stderr and exit code 2.
    """
    module = load_target(args.target)
    try:
        return run_module(module, args.target, args.bench_args)
    except RuntimeError as exc:
        print(f"dptpu bench {args.target}: error: {exc}", file=sys.stderr)
        return 2
