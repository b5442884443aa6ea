"""Launch files: validation errors name file and line; valid files resolve to the expected nodes."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from dptpu.tools.launch import (
    InlineParameter,
    LaunchFileError,
    ParameterFile,
    declared_arguments,
    load_launch_file,
    parse_launch_arguments,
)
from tests.tools.launch.conftest import FIXTURES, REPO_ROOT, TICKER


def _load(path, arguments=None, environ=None):
    return load_launch_file(path, arguments, environ=environ, cwd=REPO_ROOT)


def _error(path, arguments=None, environ=None) -> LaunchFileError:
    with pytest.raises(LaunchFileError) as caught:
        _load(path, arguments, environ)
    return caught.value


# --------------------------------------------------------------------------------------------------
# validation: file and line in every message
# --------------------------------------------------------------------------------------------------

def test_unknown_key_names_file_line_and_the_close_match(write_file):
    path = write_file("sim_rig.yaml", f"""
        launch:
          - node:
              pkg: {FIXTURES}
              exec: ticker
              name: phase
              remapp:
                - {{from: a, to: b}}
        """)
    error = _error(path)
    assert str(error) == f"{path}:6: node: unknown key 'remapp' (did you mean 'remap'?)"
    assert [(problem.line, problem.file) for problem in error.problems] == [(6, str(path))]


def test_missing_module_names_its_line_and_a_close_sibling(write_file):
    path = write_file("rig.yaml", """
        launch:
          - node: {name: a, pkg: tests.tools.launch.fixtures, exec: tickr}
        """)
    assert str(_error(path)) == (f"{path}:2: node: no module named 'tests.tools.launch.fixtures.tickr' "
                                 f"(did you mean 'ticker'?)")


def test_package_without_main_cannot_be_run_with_python_m(write_file):
    path = write_file("rig.yaml", """
        launch:
          - node: {pkg: tests.tools, exec: launch}
        """)
    assert "package without a __main__ module" in str(_error(path))


def test_undeclared_arg_is_an_error_at_the_line_that_uses_it(write_file):
    path = write_file("rig.yaml", f"""
        launch:
          - arg: {{name: rate, default: "10"}}
          - node:
              pkg: {FIXTURES}
              exec: ticker
              param:
                - name: rate
                  value: $(var rat)
        """)
    message = str(_error(path))
    assert message.startswith(f"{path}:8: param rate: undeclared launch argument 'rat' in $(var rat) "
                              f"(did you mean 'rate'?)")


def test_missing_include_file_is_an_error_at_the_include_line(write_file):
    path = write_file("main.yaml", """
        launch:
          - arg: {name: x, default: "1"}
          - include:
              file: parts/camera.yaml
        """)
    message = str(_error(path))
    assert message.startswith(f"{path}:4: include: file 'parts/camera.yaml' not found")
    assert str(path.parent / "parts" / "camera.yaml") in message


def test_include_cycle_is_reported_with_the_chain(write_file):
    write_file("b.yaml", "launch:\n  - include: {file: a.yaml}\n")
    path = write_file("a.yaml", "launch:\n  - include: {file: b.yaml}\n")
    message = str(_error(path))
    assert message.startswith(f"{path.parent / 'b.yaml'}:2: include: 'a.yaml' includes itself (")
    assert "a.yaml -> " in message and "b.yaml -> " in message


def test_include_passing_an_undeclared_arg_is_an_error_in_the_including_file(write_file):
    write_file("camera.yaml", "launch:\n  - arg: {name: rate}\n")
    path = write_file("main.yaml", """
        launch:
          - include:
              file: camera.yaml
              arg:
                - {name: rate, value: "5"}
                - {name: exposure, value: "100"}
        """)
    assert str(_error(path)) == (f"{path}:6: include: 'camera.yaml' declares no argument 'exposure' "
                                 f"(declared: rate)")


def test_included_file_missing_a_required_arg_names_the_include(write_file):
    camera = write_file("camera.yaml", "launch:\n  - arg: {name: rate}\n")
    path = write_file("main.yaml", "launch:\n  - include: {file: camera.yaml}\n")
    assert str(_error(path)) == (f"{camera}:2: arg 'rate' has no default and no value was given; the include at "
                                 f"{path}:2 must pass it (rate:=VALUE)")


def test_several_problems_are_reported_together(write_file):
    path = write_file("rig.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, nmae: a}}
          - node: {{pkg: no_such_module_xyz, exec: node}}
          - node: {{pkg: {FIXTURES}, exec: ticker, respawn_delay: soon}}
        """)
    error = _error(path)
    assert [problem.line for problem in error.problems] == [2, 3, 4]
    assert str(error).startswith("3 problems in the launch file:\n")
    assert "unknown key 'nmae' (did you mean 'name'?)" in str(error)
    assert "no module named 'no_such_module_xyz'" in str(error)
    assert "respawn_delay must be a number of seconds; got 'soon'" in str(error)


@pytest.mark.parametrize(("node_text", "line", "expected"), [
    (f"{{pkg: {FIXTURES}, exec: ticker, respawn: maybe}}", 2,
     "node: respawn must be true or false (or 1 / 0); got 'maybe'"),
    (f"{{pkg: {FIXTURES}, exec: ticker, output: scren}}", 2,
     "node: output must be one of screen, log, both; got 'scren' (did you mean 'screen'?)"),
    (f"{{pkg: {FIXTURES}, exec: ticker, param: [{{name: gains, value: [1, 2.5]}}]}}", 2,
     "param 'gains': array items must all have one type (bool, int, float or str); got float and int"),
    (f"{{pkg: {FIXTURES}, exec: ticker, param: [{{name: camera, value: {{a: 1}}}}]}}", 2,
     "param 'camera': a value cannot be a mapping"),
    (f"{{pkg: {FIXTURES}, exec: ticker, remap: [{{from: /a}}]}}", 2, "remap: missing required key 'to'"),
    ("{name: a}", 2, "node: missing required key 'exec'"),
    ("{pkg: dptpu, exec: phse}", 2, "node: pkg dptpu has no node 'phse' (did you mean 'phase'?)"),
    (f"{{pkg: {FIXTURES}, exec: ticker, on_exit: restart}}", 2,
     "node: on_exit supports only 'shutdown' (stop the launch when this node exits); got 'restart'"),
    ("{exec: no-such-program-xyz}", 2, "node: executable 'no-such-program-xyz' not found on PATH"),
    (f"{{pkg: {FIXTURES}, exec: ticker, name: my/node}}", 2, "node: name 'my/node' is not a valid node name"),
    (f"{{pkg: {FIXTURES}, exec: ticker, respawn: true, on_exit: shutdown}}", 2,
     "node: a node cannot have both on_exit: shutdown and respawn: true"),
    (f"{{pkg: {FIXTURES}, exec: ticker, respawn_delay: 2.0, respawn_max_delay: 1.0}}", 2,
     "node: respawn_max_delay (1.0 s) must be >= respawn_delay (2.0 s)"),
])
def test_bad_values_are_errors_with_file_and_line(write_file, node_text, line, expected):
    path = write_file("rig.yaml", f"launch:\n  - node: {node_text}\n")
    message = str(_error(path))
    assert message.startswith(f"{path}:{line}: {expected}"), message


def test_yaml_syntax_error_and_duplicate_key_give_their_lines(write_file):
    broken = write_file("broken.yaml", "launch:\n  - node: {exec: x\n  - arg: {name: y}\n")
    assert str(_error(broken)).startswith(f"{broken}:3: YAML syntax error")
    duplicate = write_file("duplicate.yaml", "launch:\n  - node:\n      exec: ticker\n      exec: other\n")
    assert str(_error(duplicate)) == f"{duplicate}:4: YAML syntax error: duplicate key 'exec' (first at line 3)"


def test_wrong_indentation_gets_a_hint(write_file):
    path = write_file("rig.yaml", f"launch:\n  - node:\n    pkg: {FIXTURES}\n")
    message = str(_error(path))
    assert message.startswith(f"{path}:2: a launch entry has exactly one key")
    assert "indented" in message


def test_unknown_entry_and_top_level_shape(write_file):
    path = write_file("rig.yaml", f"launch:\n  - nod: {{pkg: {FIXTURES}, exec: ticker}}\n")
    assert str(_error(path)).startswith(f"{path}:2: unknown entry 'nod' (did you mean 'node'?)")
    flat = write_file("flat.yaml", f"- node: {{pkg: {FIXTURES}, exec: ticker}}\n")
    assert str(_error(flat)).startswith(f"{flat}:1: launch file must be a mapping with one key 'launch'")


def test_command_line_arguments_must_be_declared_and_valid(write_file):
    path = write_file("rig.yaml", """
        launch:
          - arg: {name: rate, default: "10"}
          - arg: {name: mode, default: sim, choice: [{value: sim}, {value: real}]}
        """)
    assert str(_error(path, {"rat": "5"})) == (f"{path}: command line: unknown launch argument 'rat' "
                                               f"(did you mean 'rate'?); {path} declares: rate, mode")
    assert str(_error(path, {"mode": "fake"})) == f"{path}:3: arg 'mode' must be one of sim, real; got 'fake'"
    with pytest.raises(ValueError, match="launch arguments are written NAME:=VALUE"):
        parse_launch_arguments(["rate=5"])
    assert parse_launch_arguments(["rate:=5", "url:=a:=b"]) == {"rate": "5", "url": "a:=b"}


def test_duplicate_node_names_are_an_error(write_file):
    path = write_file("rig.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, name: cam, namespace: /a}}
          - node: {{pkg: {FIXTURES}, exec: ticker, name: cam, namespace: /a}}
        """)
    assert str(_error(path)).startswith(f"{path}:3: node: name '/a/cam' is used twice (first at {path}:2)")


def test_parameter_file_must_exist_and_be_a_ros2_parameter_file(write_file):
    write_file("plain.yaml", "gain: 2\n")
    path = write_file("rig.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, param: [{{from: missing.yaml}}]}}
          - node: {{pkg: {FIXTURES}, exec: ticker, param: [{{from: plain.yaml}}]}}
        """)
    error = _error(path)
    assert str(error.problems[0]).startswith(f"{path}:2: param: parameter file 'missing.yaml' not found")
    assert str(error.problems[1]).startswith(f"{path}:3: param: parameter file 'plain.yaml' is not a ROS 2 "
                                             f"parameter file")


# --------------------------------------------------------------------------------------------------
# resolution
# --------------------------------------------------------------------------------------------------

def test_node_resolves_to_the_ros2_command_line(write_file):
    params = write_file("params.yaml", "phase:\n  ros__parameters:\n    gain: 2\n")
    path = write_file("rig.yaml", f"""
        launch:
          - arg: {{name: rate, default: "10"}}
          - node:
              pkg: {FIXTURES}
              exec: ticker
              name: phase
              namespace: /scanner
              args: "--verbose 'a b'"
              param:
                - {{name: min_modulation, value: 5.0}}
                - {{name: rate, value: "$(var rate)"}}
                - {{name: label, value: "10"}}
                - {{from: params.yaml}}
                - {{name: camera, param: [{{name: exposure_us, value: [100, 200]}}]}}
              remap: [{{from: /camera/image_raw, to: /sim/image}}]
              respawn: true
              respawn_delay: 1.0
              env: [{{name: EXTRA, value: "$(var rate)"}}]
        """)
    plan = _load(path, {"rate": "20"})
    (node,) = plan.nodes
    assert plan.values == {"rate": "20"}
    assert node.parameters == (InlineParameter("min_modulation", 5.0), InlineParameter("rate", 20),
                               InlineParameter("label", "10"), ParameterFile(str(params)),
                               InlineParameter("camera.exposure_us", [100, 200]))
    assert node.command == [
        sys.executable, "-m", TICKER, "--verbose", "a b", "--ros-args",
        "-r", "__node:=phase", "-r", "__ns:=/scanner",
        "-p", "min_modulation:=5.0", "-p", "rate:=20", "-p", "label:='10'", "--params-file", str(params),
        "-p", "camera.exposure_us:=[100, 200]",
        "-r", "/camera/image_raw:=/sim/image"]
    assert (node.label, node.full_name, node.respawn, node.respawn_delay_s, node.respawn_max_delay_s) == \
        ("phase", "/scanner/phase", True, 1.0, 30.0)
    assert node.env == (("EXTRA", "20"),)
    assert node.source == f"{path}:3"


def test_include_with_args_group_namespace_and_conditions(write_file):
    write_file("parts/camera.yaml", f"""
        launch:
          - arg: {{name: cam_name}}
          - arg: {{name: rate, default: "30"}}
          - node:
              pkg: {FIXTURES}
              exec: ticker
              name: $(var cam_name)
              namespace: cam
              param: [{{name: rate, value: $(var rate)}}, {{name: dir, value: $(dirname)}}]
        """)
    path = write_file("main.yaml", f"""
        launch:
          - arg: {{name: rate, default: "10"}}
          - arg: {{name: with_extra, default: "false"}}
          - let: {{name: prefix, value: left}}
          - group:
              children:
                - push_ros_namespace: {{namespace: /rig}}
                - include:
                    file: parts/camera.yaml
                    arg:
                      - {{name: cam_name, value: $(var prefix)_camera}}
                      - {{name: rate, value: $(var rate)}}
          - node:
              if: $(var with_extra)
              pkg: no_such_module_is_checked_when_skipped
              exec: node
          - node:
              unless: $(var with_extra)
              pkg: {FIXTURES}
              exec: ticker
              name: main
        """)
    plan = _load(path, {"rate": "15"})
    camera, main = plan.nodes
    assert camera.full_name == "/rig/cam/left_camera"
    assert camera.parameters == (InlineParameter("rate", 15), InlineParameter("dir", str(path.parent / "parts")))
    assert camera.source == f"{path.parent / 'parts' / 'camera.yaml'}:4"
    assert main.full_name == "/main"
    assert main.namespace is None
    with pytest.raises(LaunchFileError, match="no module named 'no_such_module_is_checked_when_skipped'"):
        _load(path, {"with_extra": "true"})


def test_skipped_entries_still_get_their_keys_checked(write_file):
    path = write_file("rig.yaml", f"""
        launch:
          - node: {{if: "false", pkg: {FIXTURES}, exec: ticker, remapp: []}}
        """)
    assert str(_error(path)) == f"{path}:2: node: unknown key 'remapp' (did you mean 'remap'?)"


def test_env_substitution_and_executables(write_file, tmp_path):
    script = write_file("bin/node.sh", "#!/bin/sh\necho hi\n")
    script.chmod(0o755)
    path = write_file("rig.yaml", """
        launch:
          - node: {exec: bin/node.sh, name: a, param: [{name: domain, value: $(env DPTPU_DOMAIN_ID 0)}]}
          - node: {exec: sh, name: b, args: [-c, "echo $(optenv NOT_SET_XYZ fallback)"]}
        """)
    a, b = _load(path, environ={"PATH": "/usr/bin:/bin", "DPTPU_DOMAIN_ID": "7"}).nodes
    assert a.program == (str(script),)
    assert a.parameters == (InlineParameter("domain", 7),)
    assert b.program[0].endswith("/sh")
    assert b.arguments == ("-c", "echo fallback")
    bare = write_file("bare.yaml", "launch:\n  - node: {exec: sh, args: $(env NOT_SET_XYZ)}\n")
    assert str(_error(bare, environ={"PATH": "/bin"})).startswith(
        f"{bare}:2: node args: environment variable 'NOT_SET_XYZ' is not set")


def test_labels_are_unique(write_file):
    path = write_file("rig.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, name: cam, namespace: /left}}
          - node: {{pkg: {FIXTURES}, exec: ticker, name: cam, namespace: /right}}
          - node: {{pkg: {FIXTURES}, exec: ticker}}
          - node: {{pkg: {FIXTURES}, exec: ticker}}
        """)
    assert [node.label for node in _load(path).nodes] == ["left/cam", "right/cam", "ticker", "ticker-2"]


def test_declared_arguments_lists_the_top_file_args(write_file):
    path = write_file("rig.yaml", """
        launch:
          - arg: {name: rate, default: "10", description: frames per second}
          - arg: {name: mode, choice: [{value: sim}, {value: real}]}
        """)
    rate, mode = declared_arguments(path)
    assert (rate.name, rate.default, rate.description, rate.choices) == ("rate", "10", "frames per second", None)
    assert (mode.name, mode.default, mode.choices) == ("mode", None, ("sim", "real"))


def test_ros2_launch_yaml_with_group_list_push_namespace_include_let_choice_and_find_pkg_share(write_file):
    """A file as ROS 2's launch docs write one: group as a list of entities, push-ros-namespace in both spellings,
    choice, let, include through $(find-pkg-share dptpu) and $(dirname)."""
    write_file("parts/camera.yaml", f"""
        launch:
          - arg: {{name: cam_name}}
          - node: {{pkg: {FIXTURES}, exec: ticker, name: $(var cam_name), param: [{{name: dir, value: $(dirname)}}]}}
        """)
    path = write_file("main.yaml", """
        launch:
          - arg: {name: side, default: left, choice: [{value: left}, {value: right}], description: which}
          - let: {name: camera, value: $(var side)_camera}
          - group:
              - push_ros_namespace: {namespace: rig}
              - push-ros-namespace: {namespace: $(var side)}
              - include:
                  file: $(dirname)/parts/camera.yaml
                  arg: [{name: cam_name, value: $(var camera)}]
              - node: {pkg: dptpu, exec: phase, name: phase, remap: [{from: /a, to: /b}]}
          - node:
              pkg: dptpu
              exec: scan_monitor
              name: monitor
              on_exit: shutdown
              param: [{name: rig, value: $(find-pkg-share dptpu)/launch/params/twin_rig.yaml}]
        """)
    camera, phase, monitor = _load(path, {"side": "right"}).nodes
    assert camera.full_name == "/rig/right/right_camera"
    assert camera.parameters == (InlineParameter("dir", str(path.parent / "parts")),)
    assert phase.full_name == "/rig/right/phase"
    assert phase.program == (sys.executable, "-m", "dptpu.nodes.phase") and phase.remaps == (("/a", "/b"),)
    assert monitor.full_name == "/monitor" and monitor.required and monitor.module == "dptpu.nodes.scan_monitor"
    (rig,) = monitor.parameters
    assert isinstance(rig, InlineParameter) and Path(rig.value).is_file()
    assert Path(rig.value).parent.parent.name == "launch"
    assert str(_error(path, {"side": "up"})) == f"{path}:2: arg 'side' must be one of left, right; got 'up'"


@pytest.mark.parametrize(("entry", "expected"), [
    (f"node: {{module: {TICKER}}}", "node: 'module' is the old spelling; ROS 2 launch YAML writes 'pkg' and 'exec' "
                                    "(pkg: dptpu, exec: NODE runs dptpu.nodes.NODE)"),
    ("node: {executable: sh}", "node: 'executable' is the old spelling; ROS 2 launch YAML writes 'exec' "
                               "(a program without 'pkg')"),
    ("node: {exec: sh, required: true}", "node: 'required' is the old spelling; ROS 2 launch YAML writes "
                                         "'on_exit: shutdown'"),
    ("arg: {name: mode, choices: [a, b]}", "arg: 'choices' is the old spelling; ROS 2 launch YAML writes 'choice', "
                                           "a list of {value: ...} (choice: [{value: a}, {value: b}])"),
    ("group: {namespace: /rig, children: []}", "group: 'namespace' is the old spelling; ROS 2 launch YAML writes a "
                                               "'- push_ros_namespace: {namespace: NS}' entry among the group's "
                                               "children"),
])
def test_old_keys_are_refused_with_the_ros2_spelling(write_file, entry, expected):
    path = write_file("old.yaml", f"launch:\n  - {entry}\n")
    assert str(_error(path)) == f"{path}:2: {expected}"
