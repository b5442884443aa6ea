"""``dptpu rig convert``: a Bouguet pair or OpenCV calibration files -> one ``dptpu-rig/1`` (or OpenCV) rig file."""
from __future__ import annotations


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"a size must be WIDTHxHEIGHT, e.g. 640x480; got {text!r}") from None
    return width, height


def register(subparsers) -> None:
    parser = subparsers.add_parser("rig", help="rig (calibration) files")
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    convert = actions.add_parser("convert", help="convert calibration files into one rig file")
    source = convert.add_mutually_exclusive_group(required=True)
    source.add_argument("--camera", help="camera calibration: Bouguet .mat or OpenCV FileStorage .yml/.yaml/.xml")
    source.add_argument("--opencv-rig", help="an OpenCV FileStorage rig file (cam_K, cam_kc, proj_K, proj_kc, R, T)")
    convert.add_argument("--projector", help="projector calibration (with --camera): Bouguet .mat or OpenCV file")
    convert.add_argument("--camera-size", default=None, help="WIDTHxHEIGHT (default: from the file)")
    convert.add_argument("--projector-size", default=None, help="WIDTHxHEIGHT (default: from the file)")
    convert.add_argument("--pose", type=int, default=1, help="Bouguet calibration pose that defines the world "
                                                             "frame (default 1)")
    convert.add_argument("--relative-pose", choices=("view", "all-views"), default="view",
                         help="Bouguet pair: take both extrinsics from --pose (view, the toolbox's choice) or refine "
                              "the projector's pose relative to the camera over every calibration view "
                              "(all-views; docs/real-sphere.md shows the gain)")
    convert.add_argument("--units", default="mm", help="unit of the translations (default mm)")
    convert.add_argument("--to", choices=("dptpu", "opencv"), default="dptpu",
                         help="output format: dptpu-rig/1 YAML (default) or OpenCV FileStorage YAML")
    convert.add_argument("--out", required=True, help="output rig file")
    convert.set_defaults(func=run_convert)


def run_convert(args) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.fpp import calibration

    camera_size = _size(args.camera_size) if args.camera_size else None
    projector_size = _size(args.projector_size) if args.projector_size else None
    if args.opencv_rig:
        rig = calibration.load_opencv_rig(args.opencv_rig, camera_size=camera_size, projector_size=projector_size,
                                          units=args.units)
    else:
        if not args.projector:
            raise ValueError("--camera needs --projector (the projector calibration file)")
        bouguet = args.camera.lower().endswith(".mat") and args.projector.lower().endswith(".mat")
        if bouguet:
            rig = calibration.load_bouguet_pair(args.camera, args.projector, camera_size=camera_size,
                                                projector_size=projector_size, pose=args.pose, units=args.units,
                                                relative_pose=args.relative_pose)
        elif args.relative_pose != "view":
            raise ValueError("--relative-pose all-views needs a Bouguet pair (.mat files with every view's corners)")
        else:
            camera = calibration.load_device(args.camera, size=camera_size, pose=args.pose)
            projector = calibration.load_device(args.projector, size=projector_size, pose=args.pose)
            rig = calibration.Rig(camera=camera, projector=projector, units=args.units)
    if args.to == "opencv":
        calibration.save_opencv_rig(rig, args.out)
    else:
        calibration.save_rig(rig, args.out)
    print(f"wrote {args.out}: camera {rig.camera.size[0]}x{rig.camera.size[1]}, "
          f"projector {rig.projector.size[0]}x{rig.projector.size[1]}, units {rig.units}")
    return 0
