"""``dptpu bench NAME ARGS``: any ``benchmarks/NAME_bench.py`` is a target and gets ``ARGS`` unchanged.

The modules here are real files written to a temporary ``benchmarks`` folder (the command's locator is pointed
there), so the loader, the hand-over of the arguments and the exit codes run as they do for the shipped ones.
"""
from __future__ import annotations

import sys

import pytest

from dptpu.cli import bench_cmd
from dptpu.cli.main import main

WITH_MAIN = '''"""Echo benchmark: prints its argv and exits with --code."""
import argparse
import sys


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--code", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args, rest = parser.parse_known_args(argv)
    print("argv=" + "|".join(argv))
    if args.code < 0:
        raise ValueError(f"--code must be >= 0; got {args.code}")
    return args.code
'''

RUN_ONLY = '''"""Old-style benchmark: add_arguments and run, no main."""
def add_arguments(parser):
    parser.add_argument("--scans", type=int, default=3)


def run(args):
    print(f"scans={args.scans}")
    if args.scans == 99:
        raise RuntimeError("the benchmark process failed")
    return 0
'''


@pytest.fixture
def bench_folder(tmp_path, monkeypatch):
    folder = tmp_path / "benchmarks"
    folder.mkdir()
    (folder / "echo_bench.py").write_text(WITH_MAIN)
    (folder / "old_bench.py").write_text(RUN_ONLY)
    (folder / "helper.py").write_text("X = 1\n")  # not *_bench.py: not a target
    monkeypatch.setattr(bench_cmd, "benchmarks_dir", lambda: folder)
    for name in ("echo", "old"):
        monkeypatch.delitem(sys.modules, bench_cmd.module_name(name), raising=False)
    return folder


def test_targets_are_the_bench_files_with_their_first_docstring_line(bench_folder):
    assert bench_cmd.targets() == {"echo": "Echo benchmark: prints its argv and exits with --code.",
                                   "old": "Old-style benchmark: add_arguments and run, no main."}


def test_the_shipped_benchmarks_are_all_targets():
    assert {"fpp", "transport", "twin", "pipeline", "bridge"} <= set(bench_cmd.targets())


def test_args_reach_the_module_main_unchanged_and_its_code_is_the_exit_code(bench_folder, capsys):
    assert main(["bench", "echo", "--code", "3", "--json", "extra", "-x"]) == 3
    assert capsys.readouterr().out.strip() == "argv=--code|3|--json|extra|-x"
    assert main(["bench", "echo"]) == 0
    assert capsys.readouterr().out.strip() == "argv="


def test_a_value_error_of_the_module_exits_2_with_its_message(bench_folder, capsys):
    assert main(["bench", "echo", "--code", "-1"]) == 2
    assert "--code must be >= 0; got -1" in capsys.readouterr().err


def test_a_module_without_main_runs_through_add_arguments_and_run(bench_folder, capsys):
    assert main(["bench", "old", "--scans", "7"]) == 0
    assert capsys.readouterr().out.strip() == "scans=7"
    assert main(["bench", "old", "--scans", "99"]) == 2
    assert "dptpu bench old: error: the benchmark process failed" in capsys.readouterr().err


def test_help_lists_every_target(bench_folder, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["bench", "--help"])
    assert stop.value.code == 0
    out = capsys.readouterr().out
    assert "echo" in out and "Old-style benchmark" in out and "helper" not in out


def test_unknown_and_malformed_names_exit_2_naming_the_path_and_the_targets(bench_folder, capsys):
    assert main(["bench", "nope"]) == 2
    err = capsys.readouterr().err
    assert str(bench_folder / "nope_bench.py") in err and "targets found: echo, old" in err
    assert main(["bench", "../echo"]) == 2
    assert "benchmark name must be letters, digits and '_'" in capsys.readouterr().err
