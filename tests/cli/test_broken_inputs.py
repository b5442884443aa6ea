"""The CLI over broken captures, rigs and recordings: each is exit code 2 and one line on stderr that names the file,
the field and what was expected; never a traceback, never exit 0 with a wrong result (issue 19)."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest
import yaml

from dptpu.cli.main import main
from dptpu.messages import Image
from dptpu.tools.recording import McapRecordWriter


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A small twin capture (64x48, sphere, MF 16/1, four steps) with its rig, rendered once."""
    folder = tmp_path_factory.mktemp("broken") / "base"
    assert main(["sim", "render", "--rig", "nominal", "--scene", "sphere", "--sequence", "16x4,1x4", "--size",
                 "64x48", "--out", str(folder)]) == 0
    return folder


def _capture_yaml(edit):
    def mutate(folder):
        document = yaml.safe_load((folder / "capture.yaml").read_text())
        edit(document)
        (folder / "capture.yaml").write_text(yaml.safe_dump(document))
    return mutate


def _rig_yaml(edit):
    def mutate(folder):
        document = yaml.safe_load((folder / "calibration.yaml").read_text())
        edit(document)
        (folder / "calibration.yaml").write_text(yaml.safe_dump(document))
    return mutate


def _replace_with_folder(name):
    def mutate(folder):
        (folder / name).unlink()
        (folder / name).mkdir()
    return mutate


def _write_bytes(name, data: bytes):
    return lambda folder: (folder / name).write_bytes(data)


def _latin1_prefix(name):
    return lambda folder: (folder / name).write_bytes(b"\xef" + (folder / name).read_bytes()[1:])


def _gray_code(bits):
    return _capture_yaml(lambda d: d["sequences"].append(
        {"kind": "graycode", "bits": bits, "period": 60, "images": ["seq1_f1_s00.png"] * bits}))


def _set(path, value):
    """Set ``document[path[0]][path[1]]...`` to ``value``."""
    def edit(document):
        for key in path[:-1]:
            document = document[key]
        document[path[-1]] = value
    return edit


def _flip_focal(device):
    def edit(document):
        document[device]["K"][0][0] = -document[device]["K"][0][0]
    return edit


#: (id, command, mutation of the rendered folder, regex the error line must match after "error: ").
CASES = [
    ("out-is-a-folder", "unwrap", None, r"--out .*base_out-is-a-folder: is a folder; expected the path of the \.npz"),
    ("out-is-a-folder-ply", "triangulate", None, r"--out .*: is a folder; expected the path of the point cloud file"),
    ("capture-not-utf8", "unwrap", _latin1_prefix("capture.yaml"),
     r"capture\.yaml: not UTF-8 text \(byte 0xef at offset 0\); expected a capture\.yaml"),
    ("capture-yaml-a-folder", "unwrap", _replace_with_folder("capture.yaml"), r"capture\.yaml: no such file"),
    ("capture-not-yaml", "unwrap", _write_bytes("capture.yaml", b"format: [unclosed\n  - x: {"),
     r"capture\.yaml: not valid YAML \(.*line \d+"),
    ("frame-a-folder", "unwrap", _replace_with_folder("seq0_f16_s00.png"),
     r"capture\.yaml: 1 listed file\(s\) are folders, not files: seq0_f16_s00\.png"),
    ("frame-not-an-image", "unwrap", _write_bytes("seq0_f16_s00.png", b"not a png"),
     r"seq0_f16_s00\.png: not an image OpenCV can read"),
    ("projector-size-1e20", "unwrap", _capture_yaml(_set(["projector", "size"], [10**20, 1140])),
     r"capture\.yaml: projector\.size must be \[width, height\] in pixels \(two integers in \[1, 100000\]\)"),
    ("camera-size-float", "unwrap", _capture_yaml(_set(["camera", "size"], [1e20, 48])),
     r"capture\.yaml: camera\.size must be \[width, height\]"),
    ("frequency-1e308", "unwrap", _capture_yaml(lambda d: d["sequences"][0].__setitem__("frequency", 1e308)),
     r"capture\.yaml: sequences\[0\]\.frequency must be at most 456 \(a period of 2 projector pixels.*got 1e\+308"),
    ("frequency-nan", "unwrap", _capture_yaml(lambda d: d["sequences"][0].__setitem__("frequency", float("nan"))),
     r"capture\.yaml: sequences\[0\]\.frequency must be a finite number; got nan"),
    ("steps-1e9", "unwrap", _capture_yaml(lambda d: d["sequences"][0].__setitem__("steps", 10**9)),
     r"capture\.yaml: sequences\[0\]\.steps must be an integer in \[3, 1000\]; got 1000000000"),
    ("graycode-bits-2000", "unwrap", _gray_code(2000),
     r"capture\.yaml: sequences\[2\]\.bits must be an integer in \[1, 24\]; got 2000"),
    ("shift-sign-flipped", "unwrap", _capture_yaml(_set(["phase_shift_sign"], 1)),
     r"capture\.yaml: phase_shift_sign \+1 contradicts the frames: .* the frames look like phase_shift_sign -1"),
    ("shift-sign-flipped-ply", "triangulate", _capture_yaml(_set(["phase_shift_sign"], 1)),
     r"capture\.yaml: phase_shift_sign \+1 contradicts the frames"),
    ("rig-not-utf8", "triangulate", _latin1_prefix("calibration.yaml"),
     r"calibration\.yaml: not UTF-8 text \(byte 0xef at offset 0\); expected a rig file"),
    ("rig-not-yaml", "triangulate", _write_bytes("calibration.yaml", b"\x00\x01 binary"),
     r"calibration\.yaml: not valid YAML"),
    ("rig-dist-mapping", "triangulate", _rig_yaml(_set(["camera", "dist"], {})),
     r"calibration\.yaml: camera\.dist must be a list of 4 or 5 finite numbers \[k1, k2, p1, p2, k3\]; got \{\}"),
    ("rig-K-mapping", "triangulate", _rig_yaml(_set(["camera", "K"], {})),
     r"calibration\.yaml: camera: K must be numeric with shape \(3, 3\)"),
    ("rig-size-1e20", "triangulate", _rig_yaml(_set(["projector", "size"], [10**20, 1140])),
     r"calibration\.yaml: projector\.size must be \[width, height\], two integers in \[1, 100000\]"),
    ("rig-camera-focal-negative", "triangulate", _rig_yaml(_flip_focal("camera")),
     r"calibration\.yaml: camera: focal length fx \(K\[0\]\[0\]\) must be in \(0, .*got -260"),
    ("rig-projector-focal-negative", "triangulate", _rig_yaml(_flip_focal("projector")),
     r"calibration\.yaml: projector: focal length fx \(K\[0\]\[0\]\) must be in \(0, .*got -1736"),
    ("rig-focal-zero", "triangulate", _rig_yaml(lambda d: d["camera"]["K"][1].__setitem__(1, 0.0)),
     r"calibration\.yaml: camera: focal length fy \(K\[1\]\[1\]\) must be in \(0, .*got 0"),
    ("rig-focal-1e300", "triangulate", _rig_yaml(lambda d: d["camera"]["K"][0].__setitem__(0, 1e300)),
     r"calibration\.yaml: camera: focal length fx .*got 1e\+300"),
    ("rig-principal-point-far", "triangulate", _rig_yaml(lambda d: d["camera"]["K"][0].__setitem__(2, 1e6)),
     r"calibration\.yaml: camera: principal point cx \(K\[0\]\[2\]\) must lie within one panel size"),
    ("rig-distortion-absurd", "triangulate", _rig_yaml(_set(["camera", "dist"], [1e9, 0, 0, 0, 0])),
     r"calibration\.yaml: camera: distortion coefficients .* must be within \+-1000"),
    ("rig-T-1e300", "triangulate", _rig_yaml(_set(["projector", "T"], [1e300, 0.0, 0.0])),
     r"calibration\.yaml: projector centre -R\^T T lies inf m from the world origin; expected at most 1000 m"),
    ("rig-no-baseline", "triangulate", _rig_yaml(lambda d: (d["projector"].__setitem__("T", [0.0, 0.0, 0.0]))),
     r"calibration\.yaml: camera and projector centres coincide \(baseline 0 mm\)"),
    ("rig-T-nan", "triangulate", _rig_yaml(_set(["projector", "T"], [float("nan"), 0.0, 0.0])),
     r"calibration\.yaml: projector: T contains NaN or inf"),
    ("rig-units", "triangulate", _rig_yaml(_set(["units"], "furlong")),
     r"calibration\.yaml: units must be one of m, cm, mm, um; got 'furlong'"),
    ("rig-a-folder", "triangulate", _replace_with_folder("calibration.yaml"),
     r"capture\.yaml: 1 listed file\(s\) are folders, not files: calibration\.yaml"),
    ("rig-missing", "triangulate", lambda folder: (folder / "calibration.yaml").unlink(),
     r"capture\.yaml: 1 listed file\(s\) do not exist: calibration\.yaml"),
]


@pytest.mark.parametrize(("command", "mutate", "expected"), [pytest.param(*case[1:], id=case[0]) for case in CASES])
def test_broken_input_is_one_line_naming_the_problem_and_exit_2(rendered, tmp_path, capsys, request, command,
                                                                 mutate, expected):
    folder = tmp_path / f"base_{request.node.callspec.id}"
    shutil.copytree(rendered, folder)
    out = folder if mutate is None else folder / ("out.npz" if command == "unwrap" else "out.ply")
    if mutate is not None:
        mutate(folder)
    code = main([command, "--capture", str(folder), "--method", "mf", "--model", "none", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert "\n" not in err and "Traceback" not in err
    prefix = f"dptpu {command}: error: "
    assert err.startswith(prefix), err
    assert str(folder) in err or "--out" in err  # the file (or option) at fault is named
    assert re.search(expected, err[len(prefix):]), err
    assert not (folder / "out.npz").exists() and not (folder / "out.ply").exists()  # nothing written


def test_the_unbroken_capture_passes(rendered, tmp_path, capsys):
    """The table's base: the same commands succeed on the rendered folder (so each case fails for its break)."""
    for command, out in (("unwrap", tmp_path / "out.npz"), ("triangulate", tmp_path / "out.ply")):
        assert main([command, "--capture", str(rendered), "--method", "mf", "--model", "none", "--out", str(out)]) == 0
        assert out.is_file()
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(("name", "content", "expected"), [
    ("empty.mcap", b"", r"cannot read .*empty\.mcap: not an MCAP file \(EndOfFile\)"),
    ("text.mcap", b"hello\n", r"cannot read .*text\.mcap: not an MCAP file \(.+\)"),
    ("cut.mcap", None, r"cannot read .*cut\.mcap: corrupt: record at byte offset \d+: the file ends inside it"),
])
def test_play_refuses_files_that_are_not_whole_mcap(tmp_path, capsys, name, content, expected):
    path = tmp_path / name
    if content is None:
        whole = tmp_path / "whole.mcap"
        with McapRecordWriter(whole) as writer:
            for index in range(3):
                writer.write("/camera/image_raw", Image.from_array(np.full((8, 8), index, np.uint8)), 1 + index)
        content = whole.read_bytes()[: len(whole.read_bytes()) * 2 // 3]
    path.write_bytes(content)
    assert main(["play", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert re.search(expected, err), err
