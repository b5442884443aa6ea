"""The package as pyproject.toml declares it: the explicit package list against the folders, and a wheel.

The code folders sit at the repository's top level and install as subpackages of ``dptpu`` through setuptools
``package-dir``; the list of packages is written out by hand, so a folder added without its line (or a line left
for a folder that is gone) is caught here. The wheel test builds the wheel from this checkout, installs it into a
fresh virtual environment that sees the project's dependencies but not its editable install, and runs
``dptpu launch`` on the launch files the wheel installed: the main job works without a checkout.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from pathlib import Path

import pytest

from tests.graph.conftest import private_domain_env

REPO_ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())
SETUPTOOLS = PYPROJECT["tool"]["setuptools"]
#: packages that hold data only (no __init__.py): the launch files
DATA_PACKAGES = {"dptpu.launch"}
#: a private discovery domain for the wheel's graph (the other graph tests use 17 and 23)
WHEEL_DOMAIN_ID = 41


def _folder_packages() -> set[str]:
    """Every package the mapped folders hold: a folder with an ``__init__.py``, named through ``package-dir``."""
    found = set()
    for package, folder in SETUPTOOLS["package-dir"].items():
        root = REPO_ROOT / folder
        for init in root.rglob("__init__.py"):
            relative = init.parent.relative_to(root)
            found.add(".".join([package, *relative.parts]))
    return found


def test_package_list_matches_the_folders():
    declared = set(SETUPTOOLS["packages"])
    expected = _folder_packages() | DATA_PACKAGES
    assert sorted(declared - expected) == [], "pyproject.toml lists packages that have no folder with __init__.py"
    assert sorted(expected - declared) == [], "folders with an __init__.py missing from pyproject.toml's packages"


def test_every_top_level_code_folder_is_mapped():
    mapped = {Path(folder).parts[0] for folder in SETUPTOOLS["package-dir"].values()}
    code_folders = {path.parent.name for path in REPO_ROOT.glob("*/__init__.py")} - {"tests"}
    assert sorted(code_folders - mapped) == [], "a top-level code folder is not in [tool.setuptools.package-dir]"
    for package, folder in SETUPTOOLS["package-dir"].items():
        assert (REPO_ROOT / folder).is_dir(), f"package-dir maps {package} to {folder}, which does not exist"


def test_package_data_patterns_match_files():
    """Every package-data pattern matches at least one file (a moved data folder would otherwise vanish)."""
    for package, patterns in SETUPTOOLS["package-data"].items():
        folder = REPO_ROOT / SETUPTOOLS["package-dir"].get(package, "")
        if package not in SETUPTOOLS["package-dir"]:  # a subpackage: its folder under its parent's mapping
            parent, _, leaf = package.rpartition(".")
            folder = REPO_ROOT / SETUPTOOLS["package-dir"][parent] / leaf
        for pattern in patterns:
            assert any(folder.glob(pattern)), f"package-data {package}: {pattern!r} matches nothing in {folder}"


@pytest.fixture
def wheel_env(monkeypatch):
    yield from private_domain_env(monkeypatch, "dw", WHEEL_DOMAIN_ID)


def test_wheel_runs_the_main_job_from_its_installed_launch_files(tmp_path, wheel_env):
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                    "--disable-pip-version-check", "-w", str(dist), str(REPO_ROOT)],
                   check=True, cwd=tmp_path, timeout=300)
    (wheel,) = dist.glob("dptpu-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for needed in ("dptpu/launch/sim_rig.yaml", "dptpu/launch/params/shipped_rig.yaml", "dptpu/models/dptpu.onnx",
                   "dptpu/nodes/node_main.py", "dptpu/cli/main.py"):
        assert needed in names, f"{wheel.name} lacks {needed}"
    assert not any(name.startswith("dptpu/__init__") for name in names), "dptpu is a namespace package"
    assert not any(name.startswith(("tests/", "dptpu/tests/")) for name in names), "the wheel ships the tests"

    # A fresh environment whose site-packages points at the project's dependencies through a .pth line. Folders
    # named in a .pth are not scanned for .pth files themselves, so the editable install's hook is not loaded.
    venv = tmp_path / "venv"
    subprocess.run([sys._base_executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               check=True, capture_output=True, text=True).stdout.strip())
    (site / "_project_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "--no-index", "-q",
                    "--disable-pip-version-check", str(wheel)], check=True, timeout=300)

    where = subprocess.run([str(python), "-c", "import dptpu.nodes, dptpu.launch; print(dptpu.nodes.__file__); "
                                               "print(*dptpu.launch.__path__)"],
                           check=True, capture_output=True, text=True, cwd=tmp_path).stdout.split()
    assert all(Path(path).is_relative_to(site) for path in where), f"not imported from the wheel: {where}"

    env = dict(os.environ, **wheel_env)
    env.pop("PYTHONPATH", None)
    launch = subprocess.Popen([str(venv / "bin" / "dptpu"), "launch", "sim_rig.yaml", "scans:=2"], cwd=tmp_path,
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        output, _ = launch.communicate(timeout=240)
    except subprocess.TimeoutExpired:  # Ctrl-C: the launcher stops its nodes (each in its own session) first
        launch.send_signal(signal.SIGINT)
        try:
            output, _ = launch.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            launch.kill()
            output, _ = launch.communicate()
        pytest.fail(f"the installed main job did not end within 240 s:\n{output[-3000:]}")
    assert launch.returncode == 0, output[-3000:]
    scans = [line for line in output.splitlines() if line.startswith("[scan_monitor] scan ")]
    # graded, not failed: ok, or UNTRUSTED with the wrong share (the shipped random-1 has wrong orders, issue #16)
    assert len(scans) == 2 and all(": ok, " in line or ": UNTRUSTED (" in line for line in scans), output[-3000:]
    assert sorted(path.name for path in (tmp_path / "scans").glob("*.ply")), "the scan monitor wrote no PLY"
