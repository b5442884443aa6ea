"""The rig launch files validate (``dptpu launch FILE --print``), document every argument and are ROS 2 launch YAML."""
from __future__ import annotations

import pytest
import yaml

from dptpu.cli.main import main
from dptpu.tools.launch import load_launch_file
from dptpu.tools.launch.installed import installed_launch_files
from tests.launch_files.running import REPO_ROOT

LAUNCH_DIR = REPO_ROOT / "launch"
RIGS = tuple(installed_launch_files())  # every shipped top-level launch file
#: What ROS 2's YAML front end reads (launch, launch_ros): the entities and the keys of each that the files use.
ROS2_KEYS = {
    "arg": {"name", "default", "description", "choice", "if", "unless"},
    "let": {"name", "value", "if", "unless"},
    "include": {"file", "arg", "if", "unless"},
    "group": {"children", "scoped", "forwarding", "if", "unless"},
    "push_ros_namespace": {"namespace", "if", "unless"},
    "node": {"pkg", "exec", "name", "namespace", "args", "ros_args", "param", "remap", "env", "respawn",
             "respawn_delay", "on_exit", "output", "launch-prefix", "if", "unless"},
}


def test_the_shipped_rigs_are_all_checked():
    assert {"sim_rig.yaml", "dlp4500_aca640.yaml", "highspeed_dmd.yaml"} <= set(RIGS)


def _entries(entries):
    for entry in entries:
        ((kind, body),) = entry.items()
        yield kind, body
        if kind == "group":
            yield from _entries(body if isinstance(body, list) else body["children"])


@pytest.mark.parametrize("path", sorted(LAUNCH_DIR.glob("*.yaml")) + sorted((LAUNCH_DIR / "parts").glob("*.yaml")),
                         ids=lambda path: path.name)
def test_shipped_files_use_only_ros2_keys_and_paths_ros2_resolves(path):
    """ROS 2 resolves a relative include or parameter file against the working directory, so the files name them
    from $(dirname) or $(find-pkg-share dptpu); nodes are pkg: dptpu's."""
    for kind, body in _entries(yaml.safe_load(path.read_text())["launch"]):
        assert kind in ROS2_KEYS and set(body) <= ROS2_KEYS[kind], (path.name, kind, set(body) - ROS2_KEYS[kind])
        files = [body["file"]] if kind == "include" else \
            [item["from"] for item in body.get("param", []) if "from" in item] if kind == "node" else []
        for name in files:  # or a file the caller passes as an argument (the mount: its default is $(dirname)/...)
            assert name.startswith(("$(dirname)/", "$(find-pkg-share dptpu)/")) or name == "$(var mount)", \
                (path.name, name)
        if kind == "node":
            assert body["pkg"] == "dptpu", (path.name, body)


@pytest.mark.parametrize("name", RIGS)
def test_rig_launch_file_validates_with_print(name, capsys):
    assert main(["launch", str(LAUNCH_DIR / name), "--print"]) == 0
    out = capsys.readouterr().out
    for module in ("dptpu.nodes.projector", "dptpu.nodes.phase", "dptpu.nodes.unwrap", "dptpu.nodes.cloud",
                   "dptpu.nodes.scan_monitor"):
        assert f"-m {module} " in out


@pytest.mark.parametrize("name", RIGS)
def test_every_argument_has_a_description(name, capsys):
    assert main(["launch", str(LAUNCH_DIR / name), "--show-args"]) == 0
    blocks = capsys.readouterr().out.split("\n\n")[1:]  # one block per argument: name, description, default
    assert len(blocks) >= 8
    for block in blocks:
        lines = [line.strip() for line in block.strip().splitlines()]
        assert len(lines) >= 3 and lines[1] and not lines[1].startswith("(default"), block


def test_sim_rig_wires_the_shipped_renders_rig_to_the_sim_and_the_cloud():
    plan = load_launch_file(str(LAUNCH_DIR / "sim_rig.yaml"), {"size": "160x120", "scans": "3", "method": "nt",
                                                                "sequence": "96x12,10.9x12"})
    commands = {node.label: node.command for node in plan.nodes}
    assert set(commands) == {"projector", "sim", "phase", "unwrap", "cloud", "scan_monitor"}
    rig = f"rig:={LAUNCH_DIR / 'params' / 'shipped_rig.yaml'}"
    assert rig in commands["sim"] and rig in commands["cloud"] and "use_camera_info:=true" in commands["cloud"]
    assert "size:=160x120" in commands["sim"] and "method:=nt" in commands["unwrap"]
    assert "sequence:=96x12,10.9x12" in commands["sim"] and "sequence:=96x12,10.9x12" in commands["projector"]
    assert "scans:=3" in commands["scan_monitor"]
    required = {node.label for node in plan.nodes if node.required}
    assert required == {"scan_monitor"}  # its exit ends the launch


def test_real_rigs_take_the_serial_port_and_the_gentl_producer():
    plan = load_launch_file(str(LAUNCH_DIR / "dlp4500_aca640.yaml"), {"port": "/dev/ttyUSB3", "cti": "/x/P.cti"})
    commands = {node.label: " ".join(node.command) for node in plan.nodes}
    assert "port:=/dev/ttyUSB3" in commands["projector"] and "cti:=/x/P.cti" in commands["camera"]
    assert "projector_size:" not in commands["projector"]  # from params/dlp4500.yaml
    dmd = {node.label: " ".join(node.command) for node in load_launch_file(str(LAUNCH_DIR / "highspeed_dmd.yaml"),
                                                                             {}).nodes}
    assert "sequence:=96x3,1x3" in dmd["projector"] and "exposure_us:=1000" in dmd["projector"]


def test_an_unknown_argument_is_refused_with_exit_code_2(capsys):
    assert main(["launch", str(LAUNCH_DIR / "sim_rig.yaml"), "--print", "scnas:=3"]) == 2
    assert "scnas" in capsys.readouterr().err


def test_the_main_job_runs_the_network_by_default_and_grades_scans_within_the_monitors_bounds():
    plan = load_launch_file(str(LAUNCH_DIR / "sim_rig.yaml"), {})
    commands = {node.label: node.command for node in plan.nodes}
    assert "model:=auto" in commands["unwrap"]  # the shipped model wherever it serves the method and the fringes
    assert "max_wrong_share:=0.001" in commands["scan_monitor"] and "min_completeness:=0.5" in commands["scan_monitor"]
    classical = load_launch_file(str(LAUNCH_DIR / "sim_rig.yaml"), {"model": "none", "max_wrong_share": "0.01"})
    commands = {node.label: node.command for node in classical.nodes}
    assert "model:=none" in commands["unwrap"] and "max_wrong_share:=0.01" in commands["scan_monitor"]
    # the real rigs keep the classical order unless asked (their sequences are not the twin's)
    real = {node.label: node.command for node in load_launch_file(str(LAUNCH_DIR / "dlp4500_aca640.yaml"), {}).nodes}
    assert "model:=none" in real["unwrap"]


@pytest.mark.parametrize("name", RIGS)
def test_every_rig_gives_the_cloud_the_mount_file_identity_by_default(name, tmp_path):
    """The cloud's /tf_static mount comes from a parameter file: the shipped identity, or mount:=FILE (what
    ``dptpu calibrate hand-eye`` writes)."""
    default = load_launch_file(str(LAUNCH_DIR / name))
    (cloud,) = [node.command for node in default.nodes if node.label == "cloud"]
    assert str(LAUNCH_DIR / "params" / "mount.yaml") in cloud
    mount = yaml.safe_load((LAUNCH_DIR / "params" / "mount.yaml").read_text())["/**"]["ros__parameters"]
    assert mount == {"mount_frame": "scanner_mount", "mount_transform": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]}
    measured = tmp_path / "mount.yaml"
    measured.write_text("/**:\n  ros__parameters: {mount_frame: tool0}\n")
    (cloud,) = [node.command for node in load_launch_file(str(LAUNCH_DIR / name), {"mount": str(measured)}).nodes
                if node.label == "cloud"]
    assert cloud[cloud.index(str(measured)) - 1] == "--params-file"


@pytest.mark.parametrize("name", RIGS)
def test_every_rig_gives_the_phase_node_the_cloud_nodes_rig_file(name):
    """The phase node applies the rig file's projector.phase_response (dptpu calibrate response): the same file as
    the cloud's, so a calibrated response reaches every scan."""
    commands = {node.label: node.command for node in load_launch_file(str(LAUNCH_DIR / name), {}).nodes}
    rigs = [[arg for arg in commands[label] if arg.startswith("rig:=")] for label in ("phase", "cloud")]
    assert len(rigs[0]) == 1 and rigs[0] == rigs[1]
