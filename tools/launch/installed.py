"""The launch files installed with the package (``dptpu.launch``), and how a command line names one.

``dptpu launch`` takes a path, as ``ros2 launch`` takes one; where no such file exists it looks the name up among
the installed launch files, so a wheel install runs ``dptpu launch sim_rig.yaml`` (or ``sim_rig``, or the ROS 2
form ``dptpu launch dptpu sim_rig.yaml``) without a checkout. A path that exists always wins.
"""
from __future__ import annotations

import importlib
from pathlib import Path

#: The package whose data are the launch files (the repository's ``launch/`` folder).
LAUNCH_PACKAGE = "dptpu.launch"
#: The name of this package as ``ros2 launch PACKAGE FILE`` spells it.
PACKAGE_NAME = "dptpu"


def installed_launch_dir() -> Path:
    """The folder of the installed launch files (in a source checkout: ``launch/`` through the editable install)."""
    package = importlib.import_module(LAUNCH_PACKAGE)  # a data package: a namespace package without __init__.py
    return Path(next(iter(package.__path__)))


def installed_launch_files() -> list[str]:
    """File names of the installed top-level launch files, sorted (``params/`` and ``parts/`` are pieces)."""
    return sorted(path.name for path in installed_launch_dir().glob("*.yaml"))


def _as_the_user_sees_it(installed: Path) -> Path:
    """An installed file under the path its errors should name.

    An editable install links each file from a build folder (``build/__editable__.../dptpu/launch/``); an error at
    ``sim_rig.yaml:37`` should name the file one edits, ``launch/sim_rig.yaml``: the link's target, relative to the
    working directory where it lies below it. A wheel's files are no links and keep their installed path.
    """
    if not installed.is_symlink():
        return installed
    target = installed.resolve()
    try:
        return target.relative_to(Path.cwd())
    except ValueError:
        return target


def resolve_launch_file(name: str) -> Path:
    """The launch file ``name`` means: an existing path, else an installed file of that name (``.yaml`` optional).

    Raises
    ------
    FileNotFoundError
        Neither a file nor an installed launch file; the message lists the installed ones.
    """
    path = Path(name)
    if path.is_file():
        return path
    if path.exists():
        raise FileNotFoundError(f"{name}: is not a file; expected a YAML launch file")
    if path.name == name:  # a bare name, not a path: look among the installed files
        for candidate in (name, f"{name}.yaml"):
            installed = installed_launch_dir() / candidate
            if installed.is_file():
                return _as_the_user_sees_it(installed)
    choices = ", ".join(installed_launch_files()) or "none"
    raise FileNotFoundError(f"{name}: no such launch file; installed launch files: {choices}")
