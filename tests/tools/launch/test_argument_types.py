"""Launch arguments typed by their defaults: a value a statically typed parameter would refuse is refused first."""
from __future__ import annotations

import pytest

from dptpu.tools.launch.argument_types import argument_type, argument_type_problem
from tests.tools.launch.test_launch_cli import _run


@pytest.mark.parametrize(("text", "expected"), [
    ("0", "integer"), ("-12", "integer"), ("0.0", "float"), ("1e3", "float"), (".5", "float"), ("-.inf", "float"),
    ("true", "boolean"), ("False", "boolean"), ("mf", None), ("640x480", None), ("", None), ("1.2.3", None),
    ("007", "integer"),
])
def test_argument_type_follows_yaml_core_scalars(text, expected):
    assert argument_type(text) == expected


def test_a_float_argument_refuses_an_integer_and_says_how_to_write_it():
    assert argument_type_problem("frame_rate", "0.0", "2") == \
        "arg 'frame_rate' is a float (its default is '0.0'); got '2': write 2.0"
    assert argument_type_problem("frame_rate", "0.0", "2.5") is None
    assert argument_type_problem("scans", "0", "3") is None
    assert argument_type_problem("scans", "0", "three") == "arg 'scans' is an integer (its default is '0'); got 'three'"
    assert argument_type_problem("viewer", "false", "yes") == \
        "arg 'viewer' is a boolean (its default is 'false'); got 'yes': write true or false"
    assert argument_type_problem("model", "auto", "2") is None  # text: anything
    assert argument_type_problem("mode", None, "2") is None  # no default: no type


def test_launch_refuses_a_mistyped_argument_before_anything_starts(write_file):
    path = write_file("typed.yaml", """
        launch:
          - arg: {name: frame_rate, default: "0.0"}
          - node: {pkg: dptpu, exec: sim, param: [{name: frame_rate_hz, value: $(var frame_rate)}]}
        """)
    code, stdout, stderr = _run(str(path), "frame_rate:=2")
    assert code == 2
    assert stderr == (f"dptpu launch: error: {path}:2: arg 'frame_rate' is a float (its default is '0.0'); "
                      "got '2': write 2.0\n")
    assert stdout == ""
