"""``dptpu sim twin`` and ``dptpu sim setup-blender``: the twin's rig as Blender sees it, and Blender's environment.

``dptpu sim twin --rig RIG [--blender] [--json]`` prints the twin's rig (intrinsics, optical centres,
baseline, angle between the optical axes) and with ``--blender`` the Blender parameters of the paper's Table 1
for the camera and the projector (:func:`dptpu.sim.blender_params.twin_parameters`). CAL is a ``dptpu-rig/1`` or
OpenCV rig file, a Bouguet pair ``CAM.mat,PRJ.mat``, or ``nominal``.

``dptpu sim setup-blender [--env DIR] [--python PY]`` creates the Blender environment (idempotent;
:func:`dptpu.sim.blender.environment.setup_blender`).
"""
from __future__ import annotations

import json

import numpy as np

from dptpu.cli.conventions import add_renamed_option


def register(sim_subparsers) -> None:
    twin = sim_subparsers.add_parser(
        "twin", help="print the twin's rig; --blender: the Blender parameters of the paper's Table 1",
        description="Print the digital twin's rig from a calibration. With --blender, the Blender parameters of the "
                    "DP-TPU paper's Table 1 for camera and projector: location -R^T T (Eq. 13), XYZ Euler angles "
                    "(Eq. 14), focal length, principal point / lens shift, skew, spot size. See docs/blender.md.")
    twin.add_argument("--rig", required=True,
                      help="dptpu-rig/1 or OpenCV rig file, 'CAM.mat,PRJ.mat' (Bouguet), or 'nominal'")
    add_renamed_option(twin, "--calibration", "write --rig RIG (one name for a rig file in every command)")
    twin.add_argument("--blender", action="store_true", help="add the Blender parameters (Table 1)")
    twin.add_argument("--json", action="store_true", help="print JSON instead of text")
    twin.add_argument("--pixel-pitch-mm", type=float, default=None,
                      help="camera pixel pitch, sets Blender's sensor width and lens in mm (default 0.0048, the "
                           "DP-TPU camera's Basler acA640-750um)")
    twin.set_defaults(func=run_twin)
    setup = sim_subparsers.add_parser(
        "setup-blender", help="create the Blender environment (a venv with bpy 4.5) used by --engine blender",
        description="Create the Blender environment: a Python 3.11 venv with bpy 4.5 (Blender as a Python module), "
                    "kept apart from dptpu's numpy 2 environment. Idempotent. Location: --env, else "
                    "$DPTPU_BLENDER_ENV, else .blender-venv/ in the source checkout.")
    setup.add_argument("--env", default=None, help="folder of the environment")
    setup.add_argument("--python", default=None, help="Python 3.11 interpreter creating the venv")
    setup.add_argument("--quiet", action="store_true",
                       help="no progress lines (creating, installing); only the environment's path at the end")
    setup.set_defaults(func=run_setup)


def run_twin(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.sim.blender_params import DEFAULT_PIXEL_PITCH_MM, twin_parameters
    from dptpu.sim.rig import load_twin_rig

    rig = load_twin_rig(args.rig)
    pitch = DEFAULT_PIXEL_PITCH_MM if args.pixel_pitch_mm is None else args.pixel_pitch_mm
    document = {"calibration": str(args.rig), "rig": rig_summary(rig)}
    if args.blender:
        document["blender"] = twin_parameters(rig, pixel_pitch_mm=pitch)
    if args.json:
        print(json.dumps(document, indent=2))
    else:
        print(format_text(document))
    return 0


def run_setup(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.sim.blender.environment import BlenderNotInstalledError, setup_blender

    try:
        python = setup_blender(args.env, python=args.python, log=(lambda text: None) if args.quiet else print)
    except BlenderNotInstalledError as exc:
        raise ValueError(str(exc)) from None
    if args.quiet:
        print(f"Blender environment ready: {python}")
    return 0


def rig_summary(rig) -> dict:
    """Plain numbers of a rig: intrinsics, distortion, centres, baseline, angle between the optical axes."""
    axes = [device.R.T @ np.array([0.0, 0.0, 1.0]) for device in (rig.camera, rig.projector)]
    angle = float(np.degrees(np.arccos(np.clip(axes[0] @ axes[1], -1.0, 1.0))))

    def device(model) -> dict:
        return {"size": list(model.size), "K": model.K.tolist(), "dist": model.dist.tolist(),
                "center": model.center.tolist()}

    return {"units": rig.units, "camera": device(rig.camera), "projector": device(rig.projector),
            "baseline": float(np.linalg.norm(rig.camera.center - rig.projector.center)),
            "axes_angle_deg": angle}


def format_text(document: dict) -> str:
    rig = document["rig"]
    units = rig["units"]
    lines = [f"twin of {document['calibration']}  (units: {units})"]
    for name in ("camera", "projector"):
        entry = rig[name]
        K = entry["K"]
        lines.append(f"{name:9s} {entry['size'][0]}x{entry['size'][1]}  fx {K[0][0]:.3f}  fy {K[1][1]:.3f}  "
                     f"cx {K[0][2]:.3f}  cy {K[1][2]:.3f}  skew {K[0][1]:.4f}  centre "
                     + _vector(entry["center"], ".3f") + f" {units}")
    lines.append(f"baseline {rig['baseline']:.3f} {units}, angle between the optical axes "
                 f"{rig['axes_angle_deg']:.3f} deg")
    blender = document.get("blender")
    if blender:
        camera, projector = blender["camera"], blender["projector"]
        lines += ["", "Blender (the paper's Table 1; Euler mode XYZ, Eq. 14; location -R^T T, Eq. 13)",
                  "camera (perspective)",
                  f"  location        {_vector(camera['location'], '.4f')} {units}",
                  f"  rotation_euler  {_vector(camera['rotation_euler_deg'], '.4f')} deg",
                  f"  lens            {camera['lens_mm']:.4f} mm  (sensor_width {camera['sensor_width_mm']:.4f} mm, "
                  f"fit HORIZONTAL, pixel pitch {camera['pixel_pitch_mm']} mm)",
                  f"  focal length    fx {camera['focal_length_px'][0]:.3f} px, fy {camera['focal_length_px'][1]:.3f} "
                  f"px (fy/fx {camera['pixel_aspect_fy_over_fx']:.6f})",
                  f"  principal point {_vector(camera['principal_point_px'], '.3f')} px -> shift_x "
                  f"{camera['shift_x']:.6f}, shift_y {camera['shift_y']:.6f}",
                  f"  skew            {camera['skew_px']:.4f} px (factor {camera['skew_factor']:.3e})",
                  f"  not in Blender  {camera['not_in_blender']}",
                  "projector (spot light with the pattern as emission texture)",
                  f"  location        {_vector(projector['location'], '.4f')} {units}",
                  f"  rotation_euler  {_vector(projector['rotation_euler_deg'], '.4f')} deg",
                  f"  spot_size       {projector['spot_size_deg']:.4f} deg ({projector['spot_size_rad']:.6f} rad), "
                  "spot_blend 0",
                  f"  focal length    fx {projector['focal_length_px'][0]:.3f} px, fy "
                  f"{projector['focal_length_px'][1]:.3f} px",
                  f"  principal point {_vector(projector['principal_point_px'], '.3f')} px",
                  f"  skew            {projector['skew_px']:.4f} px (factor {projector['skew_factor']:.3e})",
                  f"  not in Blender  {projector['not_in_blender']}"]
    return "\n".join(lines)


def _vector(values, spec: str) -> str:
    def number(value) -> str:
        text = format(float(value), spec)
        return format(0.0, spec) if float(text) == 0.0 else text  # no "-0.0000"

    return "[" + ", ".join(number(v) for v in values) + "]"
