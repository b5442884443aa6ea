"""Launch: ROS 2 launch YAML files (a documented subset of its front end), and a supervisor for the node processes.

Typical use (what ``dptpu launch FILE name:=value`` does)::

    from dptpu.tools.launch import Supervisor, load_launch_file

    plan = load_launch_file("launch/sim_rig.yaml", {"scans": "10"})  # LaunchFileError names file:line
    for node in plan.nodes:
        print(node.label, node.command)                             # the resolved ROS 2 command lines
    exit_code = Supervisor(plan.nodes).run()                        # until Ctrl-C or an on_exit: shutdown node exits

Modules: :mod:`.launch_file` (read a file and its includes), :mod:`.launch_values` (the keys of an entry),
:mod:`.node_entries` (``node`` entries), :mod:`.launch_plan` (the result and the problems),
:mod:`.substitutions` (``$(var)``, ``$(env)``, ``$(find-pkg-share dptpu)``),
:mod:`.command_line` (``--ros-args`` as launch_ros builds it),
:mod:`.supervisor` (processes, output, respawn, shutdown), :mod:`.respawn` (backoff), :mod:`.process_groups`,
:mod:`.output_prefix`, :mod:`.marked_yaml` (YAML with line numbers), :mod:`.python_modules` (``python -m``
lookups), :mod:`.installed` (the launch files installed with the package).
The format and the behaviour are documented in ``docs/launch.md``.
"""
from __future__ import annotations

from .command_line import InlineParameter, ParameterFile, encode_parameter_value, ros_arguments
from .launch_file import declared_arguments, load_launch_file, parse_launch_arguments
from .launch_plan import LaunchArgument, LaunchFileError, LaunchPlan, LaunchProblem, NodeLaunch
from .respawn import RespawnPolicy
from .substitutions import SubstitutionError
from .supervisor import EXIT_OK, EXIT_REQUIRED_FAILED, Supervisor

__all__ = [
    "EXIT_OK",
    "EXIT_REQUIRED_FAILED",
    "InlineParameter",
    "LaunchArgument",
    "LaunchFileError",
    "LaunchPlan",
    "LaunchProblem",
    "NodeLaunch",
    "ParameterFile",
    "RespawnPolicy",
    "SubstitutionError",
    "Supervisor",
    "declared_arguments",
    "encode_parameter_value",
    "load_launch_file",
    "parse_launch_arguments",
    "ros_arguments",
]
