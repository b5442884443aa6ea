"""What loading a launch file gives: the plan (arguments, values, nodes to start) or every problem found."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from .command_line import InlineParameter, ParameterFile, ros_arguments
from .respawn import RespawnPolicy

__all__ = ["LaunchProblem", "LaunchFileError", "LaunchArgument", "NodeLaunch", "LaunchPlan", "OUTPUT_MODES",
           "DEFAULT_RESPAWN_MAX_DELAY_S"]

#: Where a node's output goes: the launcher's terminal (prefixed), a log file, or both.
OUTPUT_MODES = ("screen", "log", "both")
#: Seconds: default cap of the respawn backoff (raised to ``respawn_delay`` when that is larger).
DEFAULT_RESPAWN_MAX_DELAY_S = 30.0


@dataclass(frozen=True)
class LaunchProblem:
    """One problem in a launch file: ``file`` as displayed, 1-based ``line`` (``None``: the whole file)."""

    file: str
    line: int | None
    message: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.message}" if self.line else f"{self.file}: {self.message}"


class LaunchFileError(ValueError):
    """A launch file (or its command-line arguments) is invalid; ``problems`` lists every problem found."""

    def __init__(self, problems: Sequence[LaunchProblem]):
        self.problems = tuple(problems)
        if len(self.problems) == 1:
            text = str(self.problems[0])
        else:
            text = f"{len(self.problems)} problems in the launch file:\n" + "\n".join(
                f"  {problem}" for problem in self.problems)
        super().__init__(text)


@dataclass(frozen=True)
class LaunchArgument:
    """A declared ``arg``: ``default`` ``None`` means the value must be given."""

    name: str
    default: str | None = None
    description: str = ""
    choices: tuple[str, ...] | None = None
    source: str = ""


@dataclass(frozen=True)
class NodeLaunch:
    """One node process, fully resolved: every substitution done, every path absolute.

    label : unique short name, the ``[label]`` prefix of the node's output lines.
    source : ``file:line`` of the ``node`` entry.
    program : what runs, ``(python, "-m", module)`` or ``(/abs/executable,)``.
    module : the module for ``python -m`` nodes, else ``None``.
    arguments : extra arguments before ``--ros-args`` (the entry's ``args``).
    name, namespace : node name and absolute namespace, or ``None`` for the node's own defaults.
    parameters : ``InlineParameter`` / ``ParameterFile`` in the order written (later ones win).
    remaps : ``(from, to)`` pairs.
    env : ``(NAME, value)`` pairs set on top of the launcher's environment.
    respawn, respawn_delay_s, respawn_max_delay_s : restart on exit, first delay and backoff cap (seconds).
    required : ``on_exit: shutdown``: when it exits, everything stops (and the launch fails if its exit code is not 0).
    output : ``screen``, ``log`` or ``both``.
    """

    label: str
    source: str
    program: tuple[str, ...]
    module: str | None = None
    arguments: tuple[str, ...] = ()
    name: str | None = None
    namespace: str | None = None
    parameters: tuple[InlineParameter | ParameterFile, ...] = ()
    remaps: tuple[tuple[str, str], ...] = ()
    env: tuple[tuple[str, str], ...] = ()
    respawn: bool = False
    respawn_delay_s: float = 0.0
    respawn_max_delay_s: float = DEFAULT_RESPAWN_MAX_DELAY_S
    required: bool = False
    output: str = "screen"

    @property
    def full_name(self) -> str | None:
        """``/namespace/name`` (``/name`` without a namespace), or ``None`` when no name is set."""
        if self.name is None:
            return None
        return f"{(self.namespace or '').rstrip('/')}/{self.name}"

    @property
    def command(self) -> list[str]:
        """The argv of the process: program, ``args``, then ``--ros-args ...`` as launch_ros builds it."""
        return [*self.program, *self.arguments,
                *ros_arguments(name=self.name, namespace=self.namespace, parameters=self.parameters,
                               remaps=self.remaps)]

    @property
    def respawn_policy(self) -> RespawnPolicy:
        """Restart delays of this node (meaningful when ``respawn`` is true)."""
        return RespawnPolicy(base_delay_s=self.respawn_delay_s, max_delay_s=self.respawn_max_delay_s)


@dataclass(frozen=True)
class LaunchPlan:
    """A validated launch file: its declared arguments, their values, and the nodes to start in order."""

    path: str
    arguments: tuple[LaunchArgument, ...]
    values: Mapping[str, str]
    nodes: tuple[NodeLaunch, ...]
