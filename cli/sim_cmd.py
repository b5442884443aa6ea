"""``dptpu sim ...``: the digital twin's commands.

``dptpu sim render --rig RIG --scene SCENE --sequence 96x12,1x12 [--effects E.yaml] [--engine raycast|blender]
[--size WIDTHxHEIGHT] [--seed S] [--bit-depth 8|16] [--quiet] --out CAPTURE`` renders a ``dptpu-capture/1`` folder
with ``calibration.yaml`` and ``gt.npz`` (:func:`dptpu.sim.render.render_capture`); its stages on one tqdm line on
stderr (``--quiet``: none).

Other modules add sub-commands to the ``sim`` group when they are present: ``dptpu.cli.sim_blender_cmd``
(``sim twin``, ``sim setup-blender``) and ``dptpu.cli.sim_dataset_cmd`` (``sim dataset``); each exposes
``register(sim_subparsers)``.
"""
from __future__ import annotations

import importlib
import sys

from .conventions import add_quiet_option, stage_bar

#: Modules of ``dptpu.cli`` that add sub-commands to ``dptpu sim`` (absent ones are skipped).
SIM_COMMAND_MODULES = ("sim_blender_cmd", "sim_dataset_cmd")


def register(subparsers) -> None:
    parser = subparsers.add_parser("sim", help="digital twin: render captures, datasets, Blender setup")
    sim_subparsers = parser.add_subparsers(dest="sim_command", metavar="SIM_COMMAND", required=True)
    render = sim_subparsers.add_parser(
        "render", help="render a scene with the twin into a dptpu-capture/1 folder (frames, calibration, gt.npz)",
        description="Render a scene in the digital twin of RIG and write a dptpu-capture/1 folder with the "
                    "frames, calibration.yaml (the rig) and gt.npz (projector_x/y, depth, normals, valid, "
                    "fringe_order_<f>). See docs/twin.md and docs/effects.md.")
    render.add_argument("--rig", required=True,
                        help="dptpu-rig/1 or OpenCV rig file, 'CAM.mat,PRJ.mat' (Bouguet), or 'nominal'")
    render.add_argument("--scene", required=True,
                        help="scene YAML file, a built-in scene (sphere, plane, board), or random:SEED")
    render.add_argument("--sequence", default="96x12,1x12",
                        help="phase sequences FREQxSTEPS[:AXIS], comma separated (default 96x12,1x12; STEPS 3-1000, "
                             "FREQ at most half the projector's pixels along AXIS); 'white' and 'black' add "
                             "reference frames")
    render.add_argument("--effects", default=None, help="effects YAML (replaces the rig's effects: list)")
    render.add_argument("--engine", choices=("raycast", "blender"), default="raycast",
                        help="raycast (numpy, default) or blender (Cycles; dptpu sim setup-blender first)")
    render.add_argument("--size", default=None, help="camera render size WIDTHxHEIGHT (K is rescaled)")
    render.add_argument("--seed", type=int, default=0, help="seed of the noise and random scenes (default 0)")
    render.add_argument("--bit-depth", type=int, choices=(8, 16), default=8,
                        help="bits per pixel of the written frames (default 8)")
    render.add_argument("--meshes", default=None, help="folder of meshes for random scenes")
    render.add_argument("--supersample", type=int, default=1,
                        help="raycast rays per pixel along each axis, averaged (default 1: the pixel centre)")
    render.add_argument("--out", required=True, help="capture folder to write")
    add_quiet_option(render)
    render.set_defaults(func=run_render)
    for name in SIM_COMMAND_MODULES:
        try:
            module = importlib.import_module(f"dptpu.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"dptpu.cli.{name}":
                raise
            continue
        module.register(sim_subparsers)


def run_render(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.sim.effects import load_effects
    from dptpu.sim.image_formation import parse_sequences
    from dptpu.sim.render import render_capture
    from dptpu.sim.rig import load_twin_rig
    from dptpu.sim.scenes import load_scene, random_scene

    parse_sequences(args.sequence)  # the syntax and the step counts, before the rig is read
    with stage_bar("sim render", quiet=args.quiet) as step:
        step("reading the rig")
        rig = load_twin_rig(args.rig, size=args.size)
        sequences = parse_sequences(args.sequence, projector_size=rig.projector.size)  # every frequency: up front
        step(f"building the scene {args.scene}")
        if args.scene.startswith("random:"):
            try:
                scene_seed = int(args.scene.split(":", 1)[1])
            except ValueError:
                raise ValueError(f"--scene random:SEED needs an integer seed; got {args.scene!r}") from None
            scene = random_scene(rig, scene_seed, meshes_dir=args.meshes)
        else:
            scene = load_scene(args.scene, rig)
        effects = load_effects(args.effects) if args.effects else None
        frames = sum(1 if spec.kind != "phase" else spec.steps for spec in sequences)
        step(f"rendering {frames} frames ({args.engine}) and writing {args.out}")
        failure: RuntimeError | None = None
        try:
            out = render_capture(rig, scene, sequences, args.out, engine=args.engine, effects=effects,
                                 seed=args.seed, bit_depth=args.bit_depth, supersample=args.supersample)
        except RuntimeError as exc:  # the Blender worker: not installed (dptpu sim setup-blender), failed, timed out
            if args.engine != "blender":
                raise
            failure = exc
        else:
            step("done")
    if failure is not None:  # after the bar's line is closed, on a line of its own
        print(f"dptpu sim render: error: {failure}", file=sys.stderr)
        return 2
    print(f"wrote {out}")
    return 0
