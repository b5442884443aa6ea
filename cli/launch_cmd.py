"""``dptpu launch FILE [name:=value ...]``: validate a launch file, then run and supervise its nodes.

Like ``ros2 launch``: every node becomes its own process with the ROS 2 command line built from the
file, output lines are prefixed with ``[name]``, crashed ``respawn`` nodes come back with backoff,
Ctrl-C / SIGTERM stop everything within 5 s, and the exit code is 1 when a required node failed
(0 on a clean shutdown, 2 when the file is invalid). ``--print`` shows the resolved command lines
without starting anything; ``--show-args`` lists the file's arguments; ``--domain-id N`` runs the graph in domain
``N`` (``DPTPU_DOMAIN_ID`` for every node), so two graphs on one machine never mix. See ``docs/launch.md``.
"""
from __future__ import annotations

import argparse
import os
import shlex
import sys


def _add_options(parser, default=None) -> None:
    """The options of ``dptpu launch``; ``default=argparse.SUPPRESS`` leaves unset ones out (for the tail)."""

    def pick(value):
        return value if default is None else default

    parser.add_argument("--print", "--dry-run", dest="dry_run", action="store_true", default=pick(False),
                        help="validate and print the resolved command lines; start nothing")
    parser.add_argument("-s", "--show-args", action="store_true", default=pick(False),
                        help="list the arguments the launch file declares, then exit")
    parser.add_argument("--log-dir", default=pick(None),
                        help="folder for nodes with output: log/both (default: $DPTPU_LOG_DIR or "
                             "~/.dptpu/log, one launch-DATE-TIME-PID folder per run)")
    parser.add_argument("--domain-id", type=int, default=pick(None), metavar="ID",
                        help="the graph's domain, 0-232, for every node (sets DPTPU_DOMAIN_ID): a second graph on "
                             "this machine runs in another domain, or the two mix (default: $DPTPU_DOMAIN_ID, "
                             "$ROS_DOMAIN_ID, 0)")
    parser.add_argument("--sigint-timeout", type=float, default=pick(2.0), metavar="SECONDS",
                        help="on shutdown, seconds between SIGINT and SIGTERM (default 2.0)")
    parser.add_argument("--sigterm-timeout", type=float, default=pick(1.5), metavar="SECONDS",
                        help="on shutdown, seconds between SIGTERM and SIGKILL (default 1.5)")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "launch", help="run the nodes of a YAML launch file",
        usage="dptpu launch [options] FILE [name:=value ...] [options]",
        description="Validate a YAML launch file, then start every node as its own process and supervise "
                    "them until Ctrl-C (see docs/launch.md). Options may come before or after FILE.")
    _add_options(parser)
    parser.add_argument("file", help="YAML launch file: a path, or the name of an installed one (sim_rig.yaml); "
                                     "'dptpu FILE' as ros2 launch spells it works too")
    # everything after FILE: name:=value pairs and options in any order (parsed again in run_launch)
    parser.add_argument("tail", nargs=argparse.REMAINDER, metavar="name:=value",
                        help="values of the file's declared arguments")
    parser.set_defaults(func=run_launch)


def _parse_tail(args) -> argparse.Namespace:
    """Merge the options written after FILE into ``args``; ``args.launch_arguments`` gets the name:=value pairs."""
    tail = argparse.ArgumentParser(prog="dptpu launch", add_help=False)
    _add_options(tail, default=argparse.SUPPRESS)
    tail.add_argument("launch_arguments", nargs="*", metavar="name:=value")
    parsed = tail.parse_intermixed_args(args.tail)
    merged = argparse.Namespace(**vars(args))
    for key, value in vars(parsed).items():
        setattr(merged, key, value)
    return merged


def _launch_file(args) -> str:
    """The launch file the command line names (``dptpu launch dptpu sim_rig.yaml`` is ``ros2 launch``'s form)."""
    from dptpu.tools.launch.installed import PACKAGE_NAME, resolve_launch_file  # deferred: CLI start-up

    if args.file == PACKAGE_NAME and not os.path.exists(args.file) and args.launch_arguments \
            and ":=" not in args.launch_arguments[0]:
        args.file = args.launch_arguments.pop(0)
    return str(resolve_launch_file(args.file))


def _print_arguments(path: str) -> int:
    from dptpu.tools.launch import declared_arguments  # deferred: CLI start-up

    arguments = declared_arguments(path)
    if not arguments:
        print(f"{path} declares no arguments")
        return 0
    print("Arguments (pass arguments as '<name>:=<value>'):")
    for argument in arguments:
        print(f"\n    '{argument.name}':")
        print(f"        {argument.description or 'no description given'}")
        if argument.choices:
            print(f"        Valid choices are: {list(argument.choices)}")
        default = "(no default: required)" if argument.default is None else repr(argument.default)
        print(f"        (default: {default})")
    return 0


def _print_plan(plan) -> int:
    print(f"# {plan.path}: {len(plan.nodes)} node(s)")
    for name, value in plan.values.items():
        print(f"#   {name}:={value}")
    for node in plan.nodes:
        policy = []
        if node.respawn:
            policy.append(f"respawn (delay {node.respawn_delay_s:g} s, max {node.respawn_max_delay_s:g} s)")
        if node.required:
            policy.append("on_exit: shutdown")
        policy.append(f"output: {node.output}")
        print(f"\n[{node.label}]  # {node.source}; {', '.join(policy)}")
        env = [f"{name}={shlex.quote(value)}" for name, value in node.env]
        print(" ".join([*env, shlex.join(node.command)]))
    return 0


def _use_domain(domain_id: int) -> None:
    """``--domain-id``: checked (0..232, ValueError naming the option), then ``DPTPU_DOMAIN_ID`` of the launcher,
    which every node inherits (``$(env DPTPU_DOMAIN_ID)`` in the file reads it too)."""
    from dptpu.graph.discovery import resolve_domain_id  # deferred: CLI start-up

    try:
        resolve_domain_id(domain_id)
    except ValueError as exc:
        raise ValueError(f"--domain-id {exc.args[0].removeprefix('domain_id ')}") from None
    os.environ["DPTPU_DOMAIN_ID"] = str(domain_id)


def run_launch(args) -> int:
    """Validate and run (or print) a launch file; an invalid one prints every problem, one per line, and gives 2."""
    from dptpu.tools.launch import LaunchFileError  # deferred: CLI start-up

    try:
        return _run_launch(args)
    except LaunchFileError as exc:  # each problem on its own line (file:line: message), not joined into one
        print(f"dptpu launch: error: {exc}", file=sys.stderr)
        return 2


def _run_launch(args) -> int:
    from dptpu.tools.launch import Supervisor, load_launch_file, parse_launch_arguments  # deferred: CLI start-up

    args = _parse_tail(args)
    path = _launch_file(args)
    if args.show_args:
        return _print_arguments(path)
    for option in ("sigint_timeout", "sigterm_timeout"):
        value = getattr(args, option)
        if not 0 <= value <= 60:
            raise ValueError(f"--{option.replace('_', '-')} must be between 0 and 60 seconds; got {value}")
    if args.domain_id is not None:
        _use_domain(args.domain_id)
    plan = load_launch_file(path, parse_launch_arguments(args.launch_arguments))
    if args.dry_run:
        return _print_plan(plan)
    if not plan.nodes:
        print(f"[launch] {plan.path} starts no nodes", file=sys.stderr)
        return 0
    supervisor = Supervisor(plan.nodes, log_dir=args.log_dir, sigint_timeout_s=args.sigint_timeout,
                            sigterm_timeout_s=args.sigterm_timeout)
    return supervisor.run()
