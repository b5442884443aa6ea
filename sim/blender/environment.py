"""The Blender environment: its own virtual environment with ``bpy`` (Blender as a Python module).

bpy 4.5 pins numpy < 2 and needs Python 3.11 exactly, while dptpu runs on numpy 2, so Blender never enters
dptpu's environment: :func:`setup_blender` (``dptpu sim setup-blender``) creates a separate venv and the renderer
runs :mod:`dptpu.sim.blender.worker` under its Python.

Where: ``$DPTPU_BLENDER_ENV`` when set, else ``.blender-venv/`` at the root of a source checkout (beside
``pyproject.toml``), else ``~/.local/share/dptpu/blender-venv``.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from shutil import which

__all__ = ["BPY_REQUIREMENT", "BlenderNotInstalledError", "blender_env_dir", "blender_python",
           "installed_bpy_version", "setup_blender"]

#: What ``setup_blender`` installs: the Blender 4.5 LTS series.
BPY_REQUIREMENT = "bpy==4.5.*"
_BPY_SERIES = "4.5."


class BlenderNotInstalledError(RuntimeError):
    """The Blender environment is missing or incomplete; the message says how to create it."""


def blender_env_dir() -> Path:
    """The folder of the Blender virtual environment (it may not exist yet)."""
    if os.environ.get("DPTPU_BLENDER_ENV"):
        return Path(os.environ["DPTPU_BLENDER_ENV"]).expanduser()
    root = Path(__file__).resolve().parents[2]  # sim/blender/environment.py in a source checkout
    if (root / "pyproject.toml").is_file() and (root / "sim").is_dir():
        return root / ".blender-venv"
    return Path.home() / ".local" / "share" / "dptpu" / "blender-venv"


def _python_in(env_dir: Path) -> Path:
    return env_dir / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def installed_bpy_version(env_dir=None) -> str | None:
    """bpy's version in the environment, read from its installed metadata (no import); None when absent."""
    env_dir = Path(env_dir) if env_dir is not None else blender_env_dir()
    for dist_info in sorted(env_dir.glob("lib/python3*/site-packages/bpy-*.dist-info")) + \
            sorted(env_dir.glob("Lib/site-packages/bpy-*.dist-info")):
        if (dist_info / "METADATA").is_file():
            return dist_info.name[len("bpy-"):-len(".dist-info")]
    return None


def blender_python(env_dir=None) -> Path:
    """The Blender environment's Python executable.

    Raises
    ------
    BlenderNotInstalledError
        When the environment or its bpy is missing (run ``dptpu sim setup-blender``).
    """
    env_dir = Path(env_dir) if env_dir is not None else blender_env_dir()
    python = _python_in(env_dir)
    version = installed_bpy_version(env_dir)
    if not python.exists() or version is None:
        raise BlenderNotInstalledError(
            f"no Blender environment at {env_dir} (bpy not installed): run 'dptpu sim setup-blender' "
            "(or set DPTPU_BLENDER_ENV to an environment with bpy 4.5)")
    return python


def setup_blender(env_dir=None, *, python: str | None = None, requirement: str = BPY_REQUIREMENT,
                  log=print) -> Path:
    """Create the Blender environment and install bpy into it; does nothing when it is already there.

    Parameters
    ----------
    env_dir : path-like, optional
        Where (default :func:`blender_env_dir`).
    python : str, optional
        Python 3.11 interpreter that creates the venv (default: ``python3.11`` on PATH, else this interpreter when
        it is 3.11).
    requirement : str
        The pip requirement for bpy.
    log : callable
        Receives one line per step.

    Returns
    -------
    Path
        The environment's Python executable.
    """
    env_dir = Path(env_dir) if env_dir is not None else blender_env_dir()
    version = installed_bpy_version(env_dir)
    venv_python = _python_in(env_dir)
    if version is not None and venv_python.exists():
        if not version.startswith(_BPY_SERIES):
            log(f"note: {env_dir} has bpy {version}; dptpu is tested with {requirement}")
        log(f"Blender environment ready: {env_dir} (bpy {version})")
        return venv_python
    if not venv_python.exists():
        creator = python or _find_python311()
        log(f"creating {env_dir} with {creator}")
        _run([creator, "-m", "venv", str(env_dir)], f"could not create the venv {env_dir}")
    log(f"installing {requirement} into {env_dir} (about 350 MB download, 1 GB on disk)")
    _run([str(venv_python), "-m", "pip", "install", "--disable-pip-version-check", "-q", requirement],
         f"pip could not install {requirement} into {env_dir}")
    version = installed_bpy_version(env_dir)
    if version is None:
        raise BlenderNotInstalledError(f"pip finished but no bpy is installed in {env_dir}")
    log(f"Blender environment ready: {env_dir} (bpy {version})")
    return venv_python


def _find_python311() -> str:
    found = which("python3.11")
    if found:
        return found
    if sys.version_info[:2] == (3, 11):
        return sys.executable
    raise BlenderNotInstalledError("bpy 4.5 needs Python 3.11: none found on PATH (install python3.11 or give "
                                   "--python)")


def _run(command, failure):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        tail = (result.stderr or result.stdout).strip().splitlines()[-5:]
        raise BlenderNotInstalledError(failure + ":\n" + "\n".join(tail))

