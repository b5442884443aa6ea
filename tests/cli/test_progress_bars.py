"""The stage bars of ``dptpu unwrap``, ``triangulate`` and ``calibrate response`` on a real terminal: each stage shown
as it starts, the summary alone on stdout, nothing with ``--quiet`` (issue 18: each ran for seconds with no output).
``dptpu sim render``'s is in test_conventions.py, ``model export``'s in tests/models/test_cli.py, ``twin
diagnose``'s steps in tests/sim/diagnosis."""
from __future__ import annotations

import re
import time

import pytest

from dptpu.cli.conventions import LOG_BAR_DELAY_S, stage_bar
from dptpu.cli.main import main

from .terminal import run_on_a_terminal


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """A small calibrated twin capture (64x48 sphere, MF 16/1, four steps each)."""
    folder = tmp_path_factory.mktemp("bars") / "capture"
    assert main(["sim", "render", "--rig", "nominal", "--scene", "sphere", "--sequence", "16x4,1x4", "--size",
                 "64x48", "--quiet", "--out", str(folder)]) == 0
    return folder


def _stages(shown: str, command: str) -> list[str]:
    """The stage labels the terminal showed, in order, each once (tqdm redraws a line with '\\r')."""
    labels = []
    for line in re.split(r"[\r\n]+", shown):
        match = re.match(rf"{command}: step \d+ \[[\d:]+\] (.*?)\s*$", line.replace("\x1b[A", ""))
        if match and match.group(1) and (not labels or labels[-1] != match.group(1)):
            labels.append(match.group(1))
    return labels


def test_unwrap_shows_its_stages_on_a_terminal_and_prints_only_its_summary(capture, tmp_path):
    out = tmp_path / "phase.npz"
    code, stdout, shown = run_on_a_terminal(["unwrap", "--capture", capture, "--method", "mf", "--model", "none",
                                             "--out", out], tmp_path)
    assert code == 0, shown
    assert _stages(shown, "unwrap") == [f"reading {capture}", "wrapped phase and mf unwrapping", f"writing {out}",
                                        "done"], shown
    assert re.fullmatch(rf"mf: \d+ of 3072 pixels valid .* -> {re.escape(str(out))}\n", stdout), stdout
    code, stdout, shown = run_on_a_terminal(["unwrap", "--capture", capture, "--method", "mf", "--model", "none",
                                             "--out", out, "--quiet"], tmp_path)
    assert (code, shown) == (0, "") and stdout.startswith("mf: ")


def test_triangulate_shows_its_stages_on_a_terminal_and_prints_only_its_summary(capture, tmp_path):
    out = tmp_path / "cloud.ply"
    code, stdout, shown = run_on_a_terminal(["triangulate", "--capture", capture, "--method", "mf", "--model", "none",
                                             "--out", out], tmp_path)
    assert code == 0, shown
    assert _stages(shown, "triangulate") == [
        f"reading {capture}", "wrapped phase and mf unwrapping", "triangulating",
        "filtering depth edges and islands of a wrong order", f"writing {out}", "done"], shown
    assert re.fullmatch(rf"mf: \d+ points \(m\); .* -> {re.escape(str(out))}\n", stdout), stdout
    assert out.stat().st_size > 0


def test_calibrate_response_shows_each_capture_and_fit_on_a_terminal(tmp_path):
    folders = []
    for name, scene in (("plane", "plane"), ("sphere", "sphere")):  # 12-step references beside 3-step sequences
        folders.append(tmp_path / name)
        assert main(["sim", "render", "--rig", "nominal", "--scene", scene, "--sequence", "16x12,16x3", "--size",
                     "64x48", "--quiet", "--out", str(folders[-1])]) == 0
    out = tmp_path / "rig.yaml"
    code, stdout, shown = run_on_a_terminal(["calibrate", "response", *folders, "--out", out], tmp_path)
    assert code == 0, shown
    assert _stages(shown, "calibrate response") == [
        f"phases of {folders[0]}", f"phases of {folders[1]}", "fitting the 3-step response",
        "fitting the 4-step response", "fitting the 6-step response", "done"], shown
    assert stdout.splitlines()[-1] == (f"projector phase response of 3, 4, 6 steps from 2 capture(s) -> {out} "
                                       f"(rig {folders[0] / 'calibration.yaml'})")
    code, _, shown = run_on_a_terminal(["calibrate", "response", *folders, "--out", out, "--quiet"], tmp_path)
    assert (code, shown) == (0, "")


def test_a_stage_bar_outside_a_terminal_shows_after_the_delay_only(capsys):
    """Where stderr is not a terminal (a log, a pipe, this capture) the bar is written as the other tqdm bars are, but
    only once the command has run for LOG_BAR_DELAY_S: a fast command or a fast failure writes nothing more."""
    with stage_bar("fast", quiet=False) as step:
        step("reading")
        step("writing")
    assert capsys.readouterr().err == ""
    with stage_bar("slow", quiet=False) as step:
        step("reading")
        time.sleep(LOG_BAR_DELAY_S + 0.5)  # a long stage: the timer draws the bar in its middle
        step("writing")
    err = capsys.readouterr().err
    assert re.search(r"slow: step 1 \[00:0\d\] reading", err) and re.search(r"slow: step 2 \[00:0\d\] writing", err)
    assert err.endswith("\n"), err  # closed: the next line starts on its own
    with stage_bar("quiet", quiet=True) as step:
        step("reading")
        time.sleep(LOG_BAR_DELAY_S + 0.5)
    assert capsys.readouterr().err == ""
