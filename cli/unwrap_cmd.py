"""``dptpu unwrap``: absolute phase of a capture folder, saved as ``.npz``.

    dptpu unwrap --capture DIR --method mf|mw|nt|heterodyne|graycode [--high F --low F] [--model PATH|none]
                 [--min-confidence C] --out OUT.npz

Thin shell over :func:`dptpu.fpp.capture.read_capture` and :func:`dptpu.fpp.reconstruct.unwrap_capture`;
for mf/mw/nt the DP-TPU network (:mod:`dptpu.models.refine`, onnxruntime) refines the fringe order, by
default with the shipped model when it serves the method and the fringes (:func:`dptpu.models.refine.choose_model`;
``--model none``: the classical result). Pixels whose confidence (``reliability``: the classical rounding margin or
the network's confidence, :mod:`dptpu.fpp.confidence`) is below ``--min-confidence`` are invalid; the summary line
counts them. When the capture's ``calibration`` rig file holds the projector's response (``projector.phase_response``,
``dptpu calibrate response``) the wrapped phases of the step counts it holds are corrected first
(:meth:`dptpu.fpp.phase_harmonics.ProjectorPhaseResponse.correct`). ``dptpu triangulate`` unwraps through
:func:`unwrap_from_args` too (same defaults, same code path).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dptpu.cli.conventions import add_quiet_option, stage_bar
from dptpu.fpp.calibration import load_rig
from dptpu.fpp.capture import read_capture
from dptpu.fpp.confidence import DEFAULT_MIN_CONFIDENCE, confident
from dptpu.fpp.methods import CAPTURE_METHODS
from dptpu.fpp.nt_twins import scan_twin_warning
from dptpu.fpp.phase_direction import check_capture_phase_direction
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
    parser.add_argument("--model", metavar="PATH|none",
                        help="DP-TPU network (.onnx) that refines the mf/mw/nt fringe order; 'none' = classical; "
                             "default: the shipped model (models/dptpu.onnx) when present, for the methods it "
                             "serves (NT through its band prior when trained on MF) and fringe periods of 4 camera "
                             "pixels or more (measured on the wrapped phase)")
    parser.add_argument("--min-confidence", type=float, metavar="C",
                        help="drop pixels whose confidence in [0, 1] is lower (the classical rounding margin or the "
                             f"network's confidence, docs/nodes.md 'Confidence'); default {DEFAULT_MIN_CONFIDENCE:g} "
                             "(graycode: 0, its margin is the distance to a code edge, not to a rounding margin), "
                             "0 keeps all")
    add_quiet_option(parser, "no progress line on stderr (its stages: reading, unwrapping, the network, writing)")


@dataclasses.dataclass(frozen=True, eq=False)
class Unwrapping:
    """What :func:`unwrap_from_args` did: the result, the model applied (or None and why), the pixels dropped."""

    result: CaptureResult
    model_path: str  # "none" without a model
    note: str
    dropped_low_confidence: int
    response_note: str = ""  # what of the rig's projector.phase_response was applied ("" without one)


def unwrap_from_args(args: argparse.Namespace, step: Callable[[str], None] = lambda label: None) -> Unwrapping:
    """Read the capture named by ``args``, unwrap it, refine with the model (:func:`dptpu.models.refine.choose_model`)
    and drop what falls below ``--min-confidence``: the one code path of ``dptpu unwrap`` and ``dptpu triangulate``.
    ``step(label)`` is told each stage (:func:`dptpu.cli.conventions.stage_bar`)."""
    # imported when the command runs, not at start-up: keeps `dptpu --help` fast
    from dptpu.models.refine import choose_model, refine_capture_result, resolve_model

    min_confidence = args.min_confidence
    if min_confidence is None:
        min_confidence = 0.0 if args.method == "graycode" else DEFAULT_MIN_CONFIDENCE
    if not (0.0 <= min_confidence <= 1.0):
        raise ValueError(f"--min-confidence must be in [0, 1]; got {min_confidence:g}")
    model = resolve_model(args.model, args.method)  # before the work: a bad model file fails fast
    step(f"reading {args.capture}")
    capture = read_capture(args.capture)
    response = load_rig(capture.calibration).phase_response if capture.calibration is not None else None
    step(f"wrapped phase and {args.method} unwrapping")
    result = unwrap_capture(capture, method=args.method, high=args.high, low=args.low,
                            min_modulation=args.min_modulation, phase_response=response)
    note = ""
    if model is not None or args.model is None:
        model, note = choose_model(model, args.model, args.method, result.wrapped_phases[0], result.quality)
    if model is not None:
        step(f"refining the fringe order with {model.path.name}")
        result = refine_capture_result(result, model)
    if result.method == "nt":  # a pair whose near-twin the scan's noise can reach: said once, one line
        twin = scan_twin_warning(result.absolute_phase, result.wrapped_phases[1], result.frequencies[0],
                                 result.frequencies[1], result.valid)
        if twin is not None:
            from tqdm import tqdm  # only when warned: keeps `dptpu --help` fast

            tqdm.write(f"warning: {twin}", file=sys.stderr)  # on a line of its own above the stage bar
    check_capture_phase_direction(capture, result.absolute_phase, result.valid)  # a wrong phase_shift_sign
    valid, dropped = confident(result.reliability, result.valid, min_confidence)
    if dropped:
        result = dataclasses.replace(result, valid=valid, fringe_order=np.where(valid, result.fringe_order, 0),
                                     absolute_phase=np.where(valid, result.absolute_phase, np.nan),
                                     reliability=np.where(valid, result.reliability, 0.0))
    return Unwrapping(result=result, model_path=str(model.path) if model is not None else "none", note=note,
                      dropped_low_confidence=dropped, response_note=_response_note(result, response))


def _response_note(result: CaptureResult, response) -> str:
    """Which step counts of the rig's projector response corrected the sequences used ("" without a response)."""
    if response is None:
        return ""
    used = sorted(set(result.steps))
    corrected = [n for n in used if response.for_steps(n) is not None]
    held = ", ".join(map(str, response.steps))
    if not corrected:
        return f"projector response of the rig (steps {held}) not needed for {'/'.join(map(str, used))}-step phases"
    return f"projector response of the rig applied to {'/'.join(map(str, corrected))}-step phases"


def summary(unwrapping: Unwrapping) -> str:
    """The counts of the summary line: model, pixels dropped for low confidence."""
    parts = [f"model {unwrapping.model_path}"]
    if unwrapping.note:
        parts.append(unwrapping.note)
    if unwrapping.response_note:
        parts.append(unwrapping.response_note)
    parts.append(f"{unwrapping.dropped_low_confidence} pixels below the confidence threshold dropped")
    return "; ".join(parts)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "unwrap", help="absolute phase of a capture folder (temporal phase unwrapping) -> .npz",
        description="Unwrap the highest-frequency phase sequence of a capture folder and write an .npz with "
                    "fringe_order (int32), absolute_phase (float64, radians, phi = 2 pi f x_p / W), "
                    "valid (bool), modulation (camera DN), reliability, frequency, fringe_axis, "
                    "projector_size and method. Arrays are (H, W).")
    add_unwrap_arguments(parser)
    parser.add_argument("--out", required=True, type=Path, metavar="OUT.npz", help="output .npz file")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.out.is_dir():
        raise ValueError(f"--out {args.out}: is a folder; expected the path of the .npz file to write")
    out = args.out if args.out.suffix == ".npz" else args.out.with_name(args.out.name + ".npz")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out.parent}: output folder does not exist")
    with stage_bar("unwrap", quiet=args.quiet) as step:
        unwrapping = unwrap_from_args(args, step)
        result = unwrapping.result
        step(f"writing {out}")
        _save(out, unwrapping)
        step("done")
    total = result.valid.size
    print(f"{result.method}: {result.valid_count} of {total} pixels valid "
          f"({100.0 * result.valid_count / total:.1f}%), frequency {result.frequency:g}; {summary(unwrapping)} "
          f"-> {out}")
    return 0


def _save(out: Path, unwrapping: Unwrapping) -> None:
    """The ``.npz`` of ``dptpu unwrap``."""
    result = unwrapping.result
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
        model=np.str_(unwrapping.model_path),
    )
