"""Launch files found by name among the installed ones (``dptpu launch sim_rig.yaml`` without a checkout)."""
from __future__ import annotations

from pathlib import Path

import pytest

from dptpu.cli.main import main
from dptpu.tools.launch.installed import installed_launch_dir, installed_launch_files, resolve_launch_file
from tests.tools.launch.conftest import REPO_ROOT


def test_installed_launch_files_are_the_repository_launch_folder():
    assert installed_launch_files() == sorted(path.name for path in (REPO_ROOT / "launch").glob("*.yaml"))
    assert (installed_launch_dir() / "params" / "shipped_rig.yaml").is_file()


@pytest.mark.parametrize("name", ["sim_rig.yaml", "sim_rig"])
def test_a_bare_name_resolves_to_the_installed_file(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert resolve_launch_file(name).resolve() == (installed_launch_dir() / "sim_rig.yaml").resolve()


def test_an_installed_file_is_named_by_the_file_one_edits(monkeypatch):
    """Not ``build/__editable__.../launch/sim_rig.yaml`` (the editable install's link) in an error's file:line."""
    monkeypatch.chdir(REPO_ROOT)
    path = resolve_launch_file("sim_rig.yaml")
    assert not any("__editable__" in part for part in path.parts)
    assert path.is_file() and path.samefile(installed_launch_dir() / "sim_rig.yaml")
    if (installed_launch_dir() / "sim_rig.yaml").is_symlink():  # a source checkout's editable install
        assert path == Path("launch/sim_rig.yaml")


def test_an_argument_error_names_the_file_one_edits(monkeypatch, capsys):
    monkeypatch.chdir(REPO_ROOT)
    assert main(["launch", "sim_rig.yaml", "--print", "frame_rate:=2"]) == 2
    err = capsys.readouterr().err
    assert "__editable__" not in err
    assert "sim_rig.yaml:" in err and "arg 'frame_rate' is a float" in err


def test_an_existing_path_wins_over_an_installed_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sim_rig.yaml").write_text("launch: []\n")
    assert resolve_launch_file("sim_rig.yaml").resolve() == (tmp_path / "sim_rig.yaml").resolve()


def test_an_unknown_name_lists_the_installed_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"^nope\.yaml: no such launch file; installed launch files: .*sim_rig"):
        resolve_launch_file("nope.yaml")
    with pytest.raises(FileNotFoundError, match="no such launch file"):
        resolve_launch_file("launch/sim_rig.yaml")  # a path that does not exist is not looked up by name


def test_cli_takes_the_ros2_form_package_then_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["launch", "dptpu", "sim_rig.yaml", "--print", "scans:=3"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"# {(installed_launch_dir() / 'sim_rig.yaml').resolve()}: ")
    assert "#   scans:=3" in out


def test_cli_refuses_an_unknown_launch_file_with_exit_code_2(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["launch", "no_such_rig.yaml"]) == 2
    assert "no_such_rig.yaml: no such launch file; installed launch files: " in capsys.readouterr().err
