"""The command line's one convention: every option has help, sizes are WIDTHxHEIGHT, lists comma separated, a rig
file is --rig; old spellings are refused with one line naming the new one (exit code 2)."""
from __future__ import annotations

import argparse
import re

import pytest

from dptpu.cli.conventions import parse_list, parse_size
from dptpu.cli.main import build_parser, main

from .terminal import run_on_a_terminal


def _commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ("dptpu",)):
    """Every (command path, parser) under ``parser``, sub-commands of sub-commands included."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands(sub, (*path, name))


def _options(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if not isinstance(action, argparse._SubParsersAction | argparse._HelpAction):
            yield action


COMMANDS = list(_commands(build_parser()))


def test_the_walk_reaches_every_command_and_sub_command():
    names = {" ".join(path) for path, _ in COMMANDS}
    for expected in ("dptpu triangulate", "dptpu sim render", "dptpu sim dataset", "dptpu sim twin", "dptpu train",
                     "dptpu model toy-data", "dptpu model study", "dptpu calibrate", "dptpu param set",
                     "dptpu launch", "dptpu eval cloud", "dptpu twin diagnose"):
        assert expected in names
    assert len(names) >= 35


@pytest.mark.parametrize(("path", "parser"), COMMANDS, ids=[" ".join(path) for path, _ in COMMANDS])
def test_every_option_has_help(path, parser):
    missing = [("/".join(action.option_strings) or action.dest) for action in _options(parser)
               if not (action.help and action.help.strip())]
    assert not missing, f"{' '.join(path)}: options without help: {', '.join(missing)}"


@pytest.mark.parametrize(("path", "parser"), COMMANDS, ids=[" ".join(path) for path, _ in COMMANDS])
def test_sizes_are_width_first_and_rig_files_are_rig(path, parser):
    for action in _options(parser):
        text = f"{action.metavar or ''} {action.help or ''}"
        if action.help != argparse.SUPPRESS:
            assert not re.search(r"\bHxW\b|\bHEIGHTxWIDTH\b", text), (path, action.option_strings)
            if any(option.endswith("size") for option in action.option_strings):
                assert "WIDTHxHEIGHT" in text, (path, action.option_strings)
            assert "--calibration" not in action.option_strings and "--shape" not in action.option_strings
            # an option's list is one comma-separated value; the two that take several refuse a second (tests below)
            assert action.nargs not in ("+", "*") or not action.option_strings or \
                (path, tuple(action.option_strings)) in ((("dptpu", "sim", "dataset"), ("--noise",)),
                                                         (("dptpu", "play"), ("--topics",)))


@pytest.mark.parametrize(("argv", "expected"), [
    (["sim", "twin", "--calibration", "nominal"], "dptpu sim twin: error: --calibration is no longer accepted; write "
                                                  "--rig RIG (one name for a rig file in every command)"),
    (["train", "--data", "d", "--out", "m.onnx", "--crop", "64x32"],
     "dptpu train: error: --crop is no longer accepted; write --crop-size WIDTHxHEIGHT (width first; --crop was "
     "HEIGHTxWIDTH)"),
    (["model", "toy-data", "--out", "d", "--shape", "96x128"],
     "dptpu model toy-data: error: --shape is no longer accepted; write --size WIDTHxHEIGHT (width first; --shape "
     "was HEIGHTxWIDTH)"),
    (["model", "study", "--out", "d", "--crop", "64x64"],
     "dptpu model study: error: --crop is no longer accepted; write --crop-size WIDTHxHEIGHT (width first; --crop "
     "was HEIGHTxWIDTH)"),
])
def test_old_spellings_are_refused_in_one_line_naming_the_new_one(argv, expected, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert capsys.readouterr().err == expected + "\n"


def test_sim_dataset_noise_is_one_comma_separated_list(tmp_path, capsys):
    code = main(["sim", "dataset", "--rig", "nominal", "--scenes", "1", "--noise", "1.5693", "3.1386",
                 "--out", str(tmp_path / "d")])
    assert code == 2
    assert capsys.readouterr().err == ("dptpu sim: error: --noise takes one comma-separated list: --noise "
                                       "1.5693,3.1386 (space-separated values are no longer accepted)\n")


def test_play_topics_is_one_comma_separated_list(tmp_path, capsys):
    code = main(["play", str(tmp_path / "scan.mcap"), "--topics", "/scanner/points", "/scanner/depth"])
    assert code == 2
    assert capsys.readouterr().err == ("dptpu play: error: --topics takes one comma-separated list: --topics "
                                       "/scanner/points,/scanner/depth (space-separated topics are no longer "
                                       "accepted)\n")


def test_parse_size_and_parse_list():
    assert parse_size("640x480", "--size") == (640, 480) and parse_size(" 32X24 ", "--size") == (32, 24)
    for bad in ("640", "640x480x3", "axb", "0x480", "-1x2"):
        with pytest.raises(ValueError, match=r"^--size must be WIDTHxHEIGHT"):
            parse_size(bad, "--size")
    assert parse_list("1.5693, 3.1386", "--noise", float) == (1.5693, 3.1386)
    assert parse_list("12,3", "--steps", int) == (12, 3)
    with pytest.raises(ValueError, match=r"^--noise is a comma-separated list, e.g. 1.5693,3.1386; 'x' is not valid"):
        parse_list("1,x", "--noise", float)
    with pytest.raises(ValueError, match="without empty items"):
        parse_list("1,,2", "--noise", float)
    with pytest.raises(ValueError, match="at least one value"):
        parse_list(" ", "--noise", float)


#: Commands without ``--quiet``, each with why it shows no progress: it answers at once, or runs until stopped and
#: its stream is its output. Every other command runs long (renders, trains, evaluates, calibrates, unwraps) and
#: takes ``--quiet`` (issue 18; the outside tester's ``dptpu sim render --quiet`` was refused).
NO_PROGRESS = {
    "dptpu rig convert": "reads two files, writes one",
    "dptpu sim twin": "prints the twin's parameters",
    "dptpu bench": "ARGS go unchanged to the benchmark, whose measurements are its output",
    "dptpu launch": "runs the graph until stopped; the nodes' lines are its output",
    "dptpu record": "runs until stopped",
    "dptpu play": "its progress is the played messages",
}
_INTROSPECTION = ("dptpu node ", "dptpu topic ", "dptpu param ", "dptpu service ")  # ros2's verbs: answer or stream


def _leaves():
    return [(" ".join(path), parser) for path, parser in COMMANDS
            if not any(isinstance(action, argparse._SubParsersAction) for action in parser._actions)]


def test_every_long_running_command_takes_quiet():
    leaves = dict(_leaves())
    assert set(NO_PROGRESS) <= set(leaves)  # the list names real commands
    missing = [name for name, parser in leaves.items()
               if name not in NO_PROGRESS and not name.startswith(_INTROSPECTION)
               and "--quiet" not in {option for action in parser._actions for option in action.option_strings}]
    assert not missing, f"commands without --quiet: {', '.join(missing)}"
    for name in ("dptpu sim render", "dptpu unwrap", "dptpu triangulate", "dptpu twin finetune",
                 "dptpu sim setup-blender", "dptpu model toy-data", "dptpu model export"):
        assert name in leaves and name not in NO_PROGRESS


def test_an_unrecognized_argument_is_refused_with_the_sub_commands_usage(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["sim", "render", "--rig", "nominal", "--scene", "sphere", "--out", str(tmp_path / "c"), "--bogus"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: dptpu sim render [-h] --rig RIG"), err  # not "usage: dptpu [-h] COMMAND ..."
    assert err.splitlines()[-1] == "dptpu sim render: error: unrecognized arguments: --bogus"
    with pytest.raises(SystemExit):
        main(["param", "get", "/cloud", "frame_id", "--bogus"])
    assert capsys.readouterr().err.startswith("usage: dptpu param get ")
    with pytest.raises(SystemExit):
        main(["--bogus"])
    assert capsys.readouterr().err.startswith("usage: dptpu [-h] COMMAND")


def test_sim_render_shows_its_stages_on_a_terminal_and_quiet_shows_none(tmp_path):
    render = ["sim", "render", "--rig", "nominal", "--scene", "sphere", "--size", "64x48", "--sequence", "16x3,1x3"]
    code, out, shown = run_on_a_terminal([*render, "--out", str(tmp_path / "a")], tmp_path)
    assert code == 0 and "sim render: step" in shown and "rendering 6 frames (raycast)" in shown, shown
    assert out == f"wrote {tmp_path / 'a'}\n"  # the bar is on stderr only
    code, _, shown = run_on_a_terminal([*render, "--out", str(tmp_path / "b"), "--quiet"], tmp_path)
    assert (code, shown) == (0, "")
    assert (tmp_path / "b" / "capture.yaml").is_file()
