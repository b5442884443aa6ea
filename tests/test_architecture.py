"""The rules between packages of docs/architecture.md, checked on every import of every module of the code folders.

Every ``.py`` file of the code folders is parsed with :mod:`ast`; module-level, function-local and
``TYPE_CHECKING`` imports all count, relative imports are resolved against the file's own module. A failure names
each ``file:line`` and the forbidden import.
"""
from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Top-level folders that are code (a subpackage of ``dptpu``): those holding an ``__init__.py``.
CODE_FOLDERS = tuple(sorted(p.parent.name for p in ROOT.glob("*/__init__.py") if p.parent.name != "tests"))
#: What each package may import of ours, besides itself (docs/architecture.md, "Rules between packages").
ALLOWED = {
    "fpp": set(),
    "messages": set(),
    "graph": {"messages"},
    "tools": {"graph", "messages"},
    "sim": {"fpp"},
    "models": {"fpp"},
    "experiments": {"sim", "models", "fpp"},
    "nodes": {"graph", "messages", "fpp", "models", "sim"},
    "cli": set(CODE_FOLDERS) - {"nodes"},
}


@dataclass(frozen=True)
class Import:
    """One imported name: where (``file:line``), the importing package, what it imports (``dptpu.sim.rig`` for
    ``import dptpu.sim.rig``, ``dptpu.sim.rig.trace`` for ``from dptpu.sim.rig import trace``), whether the
    statement sits inside a function, and the statement's first line."""

    file: str
    line: int
    package: str
    module: str
    local: bool
    source: str = ""

    @property
    def target(self) -> str | None:
        """The package of ours it reaches (``sim`` for ``dptpu.sim.rig``), or None for anything else."""
        parts = self.module.split(".")
        return parts[1] if len(parts) > 1 and parts[0] == "dptpu" else None

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.source or 'import ' + self.module}" + (
            " (inside a function)" if self.local else "")


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(["dptpu", *parts])


def _resolve(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The absolute module of ``from ... import`` (relative levels counted from the file's own package)."""
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports_of(path: Path, root: Path = ROOT) -> list[Import]:
    text = path.read_text()
    lines = text.splitlines()
    tree = ast.parse(text, filename=str(path))
    module = _module_name(path, root)
    package = module.split(".")[1]
    relative_file = str(path.relative_to(root))
    found = []

    def visit(node: ast.AST, local: bool) -> None:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            source = lines[node.lineno - 1].strip()
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            else:  # each name may be a module (from dptpu import sim; from . import phase) or a name in one
                base = _resolve(node, module, path.name == "__init__.py")
                names = [f"{base}.{alias.name}" for alias in node.names]
            found.extend(Import(relative_file, node.lineno, package, name, local, source) for name in names)
        inside = local or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
        for child in ast.iter_child_nodes(node):
            visit(child, inside)

    visit(tree, False)
    return found


@cache
def all_imports() -> tuple[Import, ...]:
    found = []
    for folder in CODE_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            found.extend(_imports_of(path))
    return tuple(found)


def _forbidden(package: str, allowed: set[str]) -> list[Import]:
    return [i for i in all_imports()
            if i.package == package and i.target is not None and i.target != package and i.target not in allowed]


def _report(rule: str, offending: list[Import]) -> str:
    statements = list(dict.fromkeys(str(i) for i in offending))  # one line per statement, in file order
    return f"{rule} (docs/architecture.md); {len(statements)} forbidden import(s):\n" + "\n".join(
        f"  {line}" for line in statements)


def test_the_import_scan_sees_module_level_local_relative_and_type_checking_imports(tmp_path):
    source = ("from __future__ import annotations\nfrom typing import TYPE_CHECKING\nfrom . import phase\n"
              "from ..sim import rig\nfrom dptpu import models\nif TYPE_CHECKING:\n    import dptpu.graph.node\n"
              "def f():\n    from dptpu.nodes.unwrap import node\n")
    folder = tmp_path / "fpp"
    folder.mkdir()
    (folder / "example.py").write_text(source)
    found = {(i.module, i.target, i.local) for i in _imports_of(folder / "example.py", tmp_path)}
    assert {("dptpu.fpp.phase", "fpp", False), ("dptpu.sim.rig", "sim", False), ("dptpu.models", "models", False),
            ("dptpu.graph.node", "graph", False), ("dptpu.nodes.unwrap.node", "nodes", True)} <= found


def test_every_code_folder_has_a_rule():
    assert set(CODE_FOLDERS) == set(ALLOWED), (
        f"code folders without a rule in tests/test_architecture.py (and docs/architecture.md): "
        f"{sorted(set(CODE_FOLDERS) - set(ALLOWED))}; rules for folders that are gone: "
        f"{sorted(set(ALLOWED) - set(CODE_FOLDERS))}")


def test_fpp_imports_nothing_of_ours():
    offending = _forbidden("fpp", ALLOWED["fpp"])
    assert not offending, _report("fpp (the measurement core) imports nothing of ours", offending)


def test_messages_imports_nothing_of_ours():
    offending = _forbidden("messages", ALLOWED["messages"])
    assert not offending, _report("messages imports nothing of ours", offending)


def test_graph_imports_only_messages():
    offending = _forbidden("graph", ALLOWED["graph"])
    assert not offending, _report("graph (the runtime) imports only messages", offending)


def test_graph_never_imports_the_scanner_messages():
    offending = [i for i in all_imports() if i.package == "graph"
                 and (i.module == "dptpu.messages.scanner" or i.module.startswith("dptpu.messages.scanner."))]
    assert not offending, _report("graph never imports messages.scanner (the runtime knows no scanner)", offending)


def test_tools_import_only_graph_and_messages():
    offending = _forbidden("tools", ALLOWED["tools"])
    assert not offending, _report("tools (launch, recording, introspection) import only graph and messages",
                                  offending)


def test_sim_imports_only_fpp():
    offending = _forbidden("sim", ALLOWED["sim"])
    assert not offending, _report("sim (the twin) imports only fpp", offending)


def test_models_imports_only_fpp():
    offending = _forbidden("models", ALLOWED["models"])
    assert not offending, _report("models (the network) imports only fpp", offending)


def test_experiments_import_only_sim_models_and_fpp():
    offending = _forbidden("experiments", ALLOWED["experiments"])
    assert not offending, _report("experiments import only sim, models and fpp", offending)


def test_nodes_import_only_graph_messages_fpp_models_and_sim():
    offending = _forbidden("nodes", ALLOWED["nodes"])
    assert not offending, _report("nodes import only graph, messages, fpp, models and sim", offending)


def test_cli_imports_anything_but_nodes():
    offending = _forbidden("cli", ALLOWED["cli"])
    assert not offending, _report("cli may import anything but nodes", offending)


def test_nothing_imports_nodes():
    offending = [i for i in all_imports() if i.target == "nodes" and i.package != "nodes"]
    assert not offending, _report("nothing imports nodes (tests, benchmarks and launch files may)", offending)


def _says_why(lines: list[str], node_line: int, end_line: int, import_lines: set[int]) -> bool:
    """A comment on the import's own lines, or on the line above the block of imports it belongs to."""
    if any("#" in lines[n - 1] for n in range(node_line, end_line + 1)):
        return True
    n = node_line - 1
    while n >= 1 and (not lines[n - 1].strip() or n in import_lines):
        n -= 1
    return n >= 1 and lines[n - 1].strip().startswith("#")


def test_function_local_imports_say_why():
    offending = []
    for folder in CODE_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            text = path.read_text()
            lines = text.splitlines()
            tree = ast.parse(text)
            statements = [n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]
            import_lines = {line for n in statements for line in range(n.lineno, n.end_lineno + 1)}
            local = {i.line for i in _imports_of(path) if i.local}
            for node in statements:
                if node.lineno in local and not _says_why(lines, node.lineno, node.end_lineno, import_lines):
                    offending.append(f"  {path.relative_to(ROOT)}:{node.lineno}: {lines[node.lineno - 1].strip()}")
    assert not offending, (
        "a function-local import stays only for a heavy or optional dependency (torch, onnx, bpy, open3d, "
        "matplotlib) or the CLI's start-up time, with a comment saying which; else it goes to the top of the "
        f"module (docs/architecture.md). {len(offending)} without a comment:\n" + "\n".join(offending))


def test_the_architecture_page_names_every_code_folder():
    text = (ROOT / "docs" / "architecture.md").read_text()
    missing = [f for f in CODE_FOLDERS + ("launch",) if not re.search(rf"`{f}/`", text)]
    assert not missing, f"docs/architecture.md does not name the code folder(s) {missing} (as `name/`)"


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_the_architecture_page_states_each_rule(package):
    text = (ROOT / "docs" / "architecture.md").read_text()
    assert re.search(rf"^{package}\s+->", text, re.MULTILINE), (
        f"docs/architecture.md, 'Rules between packages', has no line '{package} -> ...'")
