"""``dptpu unwrap``: absolute phase of a capture folder, saved as ``.npz``.

    dptpu unwrap --capture DIR --method mf|mw|nt|heterodyne|graycode [--high F --low F] [--model PATH|none]
                 --out OUT.npz

Thin shell over :func:`dptpu.fpp.capture.read_capture` and :func:`dptpu.fpp.reconstruct.unwrap_capture`;
for mf/mw/nt the DP-TPU network (:mod:`dptpu.models.refine`, onnxruntime) refines the fringe order, by
default with the shipped model when the package has one (``--model none``: the classical result).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dptpu.fpp.capture import read_capture
from dptpu.fpp.methods import CAPTURE_METHODS
from dptpu.fpp.reconstruct import (
    DEFAULT_MIN_MODULATION_FRACTION,
    CaptureResult,
    unwrap_capture,
)

#: Keys of the written ``.npz``.
NPZ_KEYS = ("fringe_order", "absolute_phase", "valid", "modulation", "reliability", "frequency",
            "fringe_axis", "projector_size", "method", "model")


def add_unwrap_arguments(parser: argparse.ArgumentParser) -> None:
    """The options shared by ``unwrap`` and ``triangulate``: capture, method, sequence choice, threshold."""
    parser.add_argument("--capture", required=True, type=Path, metavar="DIR",
                        help="capture folder (dptpu-capture/1, docs/capture-format.md) or its capture.yaml")
    parser.add_argument("--method", required=True, choices=CAPTURE_METHODS,
                        help="temporal unwrapping: mf (f_l <= 1), mw (f_h - f_l <= 1), nt (number-theoretic), "
                             "heterodyne (every phase sequence), graycode (Gray-code sequence)")
    parser.add_argument("--high", type=float, metavar="F",
                        help="frequency (periods across the projector) of the sequence to unwrap; "
                             "default: the highest")
    parser.add_argument("--low", type=float, metavar="F",
                        help="frequency of the auxiliary sequence; default: lowest (mf), f_h - f_l <= 1 (mw), "
                             "the other one (nt)")
    parser.add_argument("--min-modulation", type=float, metavar="DN",
                        help="smallest fringe modulation B of a valid pixel, camera digital numbers; default "
                             f"{DEFAULT_MIN_MODULATION_FRACTION:g} of full scale (5.1 for 8-bit frames)")


def unwrap_from_args(args: argparse.Namespace) -> CaptureResult:
    """Read the capture named by ``args`` and unwrap it."""
    capture = read_capture(args.capture)
    return unwrap_capture(capture, method=args.method, high=args.high, low=args.low,
                          min_modulation=args.min_modulation)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "unwrap", help="absolute phase of a capture folder (temporal phase unwrapping) -> .npz",
        description="Unwrap the highest-frequency phase sequence of a capture folder and write an .npz with "
                    "fringe_order (int32), absolute_phase (float64, radians, phi = 2 pi f x_p / W), "
                    "valid (bool), modulation (camera DN), reliability, frequency, fringe_axis, "
                    "projector_size and method. Arrays are (H, W).")
    add_unwrap_arguments(parser)
    parser.add_argument("--model", metavar="PATH|none",
                        help="DP-TPU network (.onnx) that refines the mf/mw/nt fringe order; 'none' = classical; "
                             "default: the shipped model (models/dptpu.onnx) when present, for the methods it "
                             "serves (NT through its band prior when trained on MF) and fringe periods of 4 camera "
                             "pixels or more")
    parser.add_argument("--out", required=True, type=Path, metavar="OUT.npz", help="output .npz file")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.models.refine import (
        DEFAULT_MAX_PERIODS_PER_PIXEL,
        fringe_density,
        refine_capture_result,
        resolve_model,
    )

    model = resolve_model(args.model, args.method)  # before the work: a bad model file fails fast
    result = unwrap_from_args(args)
    if model is not None and args.model is None and fringe_density(result) > DEFAULT_MAX_PERIODS_PER_PIXEL:
        model = None  # the shipped model by default only within its training domain (fringe periods >= 4 px)
    if model is not None:
        result = refine_capture_result(result, model)
    out = args.out if args.out.suffix == ".npz" else args.out.with_name(args.out.name + ".npz")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out.parent}: output folder does not exist")
    np.savez_compressed(
        out,
        fringe_order=result.fringe_order,
        absolute_phase=result.absolute_phase,
        valid=result.valid,
        modulation=result.modulation,
        reliability=result.reliability,
        frequency=np.float64(result.frequency),
        fringe_axis=np.str_(result.fringe_axis),
        projector_size=np.asarray(result.projector_size, dtype=np.int64),
        method=np.str_(result.method),
        model=np.str_(str(model.path) if model is not None else "none"),
    )
    total = result.valid.size
    print(f"{result.method}: {result.valid_count} of {total} pixels valid "
          f"({100.0 * result.valid_count / total:.1f}%), frequency {result.frequency:g} -> {out}")
    return 0
