"""``dptpu bench unwrap_dptpu``: the unwrap node's DP-TPU path at a base commit against the working tree's, side by side
in one process, outputs compared bit for bit (not a test).

The pipeline bench's DP-TPU row (``dptpu bench pipeline --dptpu-only``) gives the unwrap process's CPU a scan among
the graph's other processes; on a shared machine its run-to-run spread is larger than a cut of a few milliseconds.
This bench times what the node does with one scan's PhaseMaps in one process, twice: with the ``fpp`` and ``models``
packages of ``--base`` (taken from git with ``git archive`` into a temporary folder and imported under another name,
their imports of ``dptpu.fpp`` / ``dptpu.models`` renamed with them) and with the installed ones, on the same maps,
alternating the two every repeat (the machine's other load falls on both alike). Its parts, as the node runs them:

- ``floor``: the agreement's rounding floor from the modulations (``integer_frames_floor``);
- ``refine``: :func:`dptpu.models.refine.refinement` (``refine_order_and_confidence`` at a base without it) with the
  shipped model on 1 thread, consensus off (the launch files' default) or on (``--consensus``): the network's prior,
  the network, the confidence, the two frequencies' agreement and the region test; then the published absolute phase
  (the node's ``refined``: NaN where not valid);
- inside it, from each side's ``fpp`` on the working tree's network output: ``network_confidence``,
  ``frequency_consistency`` and ``rejected_regions``.

The maps are the phase node's (:func:`dptpu.fpp.scan_phase.scan_phase_maps`, 2 x 12 steps, 64 and 1 periods) of the
graph's first scene: random-1 rendered as the sim node renders it (``raycast``) or a capture folder's first capture.
Before timing, both sides' outputs are compared bit for bit (order, confidence, absolute phase and each part's); a
difference is reported (``outputs_differing``) and makes the exit code 1. Each part's median and fastest CPU time
(``time.process_time``) after :data:`WARMUPS` untimed repeats, and the median of the paired differences. Run from a
source checkout (git)::

    dptpu bench unwrap_dptpu [--base 6669a7e] [--source FOLDER|raycast] [--size 640x480] [--repeats 20]
                             [--consensus] [--json]

Results: docs/benchmarks.md, "Model: the unwrap node's DP-TPU path, session 10".
"""
from __future__ import annotations

import argparse
import importlib
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
SHIPPED_RIG = REPO_ROOT / "launch" / "params" / "shipped_rig.yaml"
#: The graph's sequence (the pipeline bench's 2 x 12-step DP-TPU row) and its frequencies.
SEQUENCE, F_H, F_L, STEPS = "64x12,1x12", 64.0, 1.0, 12
#: The scene the graph scans first (the pipeline bench's first raycast scene).
FIRST_SCENE = "random:1"
#: The name the base's ``fpp`` and ``models`` are imported under (``BASE_PACKAGE.fpp``, ``BASE_PACKAGE.models``).
BASE_PACKAGE = "dptpu_unwrap_base"
PARTS = ("floor", "refine", "network_confidence", "frequency_consistency", "rejected_regions")
#: Untimed repeats a side first: the heap grows to what a scan needs.
WARMUPS = 3


def extract_base(commit: str, folder: Path) -> str:
    """``git archive`` the ``fpp`` and ``models`` folders of ``commit`` into ``folder/BASE_PACKAGE``, their absolute
    imports of each other renamed; the package name."""
    archive = subprocess.run(["git", "-C", str(REPO_ROOT), "archive", commit, "fpp", "models"], capture_output=True,
                             check=False)
    if archive.returncode != 0:
        raise ValueError(f"git archive {commit} fpp models failed: {archive.stderr.decode(errors='replace').strip()}")
    package = folder / BASE_PACKAGE
    package.mkdir()
    subprocess.run(["tar", "-x", "-C", str(package)], input=archive.stdout, check=True)
    (package / "__init__.py").write_text("")
    for path in package.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        renamed = re.sub(r"\bdptpu\.(fpp|models)\b", rf"{BASE_PACKAGE}.\1", text)
        if renamed != text:
            path.write_text(renamed, encoding="utf-8")
    return BASE_PACKAGE


def scan_maps(source: str, size: str) -> dict:
    """The phase node's maps of the graph's first scene: ``phases``, ``modulation`` (2, H, W) float32, ``valid``."""
    from dptpu.fpp.scan_phase import scan_phase_maps
    from dptpu.nodes.sim.source import load_source

    loaded = load_source(source, rig=str(SHIPPED_RIG), size=size, scenes=FIRST_SCENE, sequence=SEQUENCE)
    stacks = [loaded.scenes[0].stack(frequency, STEPS) for frequency in (F_H, F_L)]
    if any(stack is None for stack in stacks):
        raise ValueError(f"the first scene of {source} holds no 64x12 and 1x12 sequences")
    phases, modulation, valid = scan_phase_maps([np.ascontiguousarray(s) for s in stacks], [0.0, 0.0], shift_sign=-1,
                                                min_modulation=10.0, saturation_level=None)
    return {"phases": phases, "modulation": modulation, "valid": valid}


class Side:
    """One side's ``fpp`` and ``models`` (``dptpu`` or the base's) and its parts on one scan's maps."""

    def __init__(self, package: str, maps: dict, model_path: Path, consensus: bool) -> None:
        def module(name: str):
            return importlib.import_module(f"{package}.{name}")

        self.refine = module("models.refine")
        self.consistency = module("fpp.frequency_consistency")
        self.confidence = module("fpp.confidence")
        self.regions = module("fpp.region_consistency")
        tpu = module("fpp.tpu")
        self.model = module("models.inference").FringeOrderModel.load(model_path, threads=1)
        self.maps, self.consensus = maps, consensus
        phases = maps["phases"]
        self.classical = tpu.unwrap_mf_float32(phases[0], phases[1], F_H, F_L, valid=maps["valid"])
        self.out: dict[str, np.ndarray] = {}

    def floor(self) -> None:
        modulation = self.maps["modulation"]
        self.out["floor"] = self.consistency.integer_frames_floor(modulation[0], modulation[1], STEPS, STEPS, F_H, F_L)

    def refine_scan(self) -> None:
        phases, result = self.maps["phases"], self.classical
        args = (self.model, "mf", phases[0], phases[1], result.fringe_order, F_H, F_L, result.valid)
        options = {"consensus": self.consensus, "consistency_floor": self.out["floor"],
                   "modulation": self.maps["modulation"][0]}
        if hasattr(self.refine, "refinement"):
            order, confidence, absolute = self.refine.refinement(*args, **options)
        else:  # before refinement: the node computed the absolute phase again
            order, confidence = self.refine.refine_order_and_confidence(*args, **options)
            absolute = phases[0].astype(np.float64) + 2.0 * np.pi * order
        self.out.update(order=order, confidence=confidence,
                        absolute=np.where(result.valid, absolute, np.nan))

    def parts(self, inputs: dict) -> None:
        """The confidence's three parts on the same inputs (the working tree's network output)."""
        self.out["network_confidence"] = self.confidence.network_confidence(
            inputs["continuous"], inputs["order"], inputs["prior"], inputs["mask"], wrapped_high=inputs["wrapped"])
        self.out["frequency_consistency"] = self.consistency.frequency_consistency(
            inputs["absolute"], inputs["psi_l"], F_H, F_L, inputs["mask"], floor=self.out["floor"])
        self.out["rejected_regions"] = self.regions.rejected_regions(inputs["absolute"], inputs["psi_l"], F_H, F_L,
                                                                     inputs["mask"])


def part_inputs(side: Side) -> dict:
    """The network output and the order the confidence's parts judge (the working tree's, consensus off)."""
    from dptpu.models.refine import network_prior

    phases, result = side.maps["phases"], side.classical
    mask = np.asarray(result.valid, bool)
    wrapped_low, prior = network_prior("mf", phases[0], phases[1], result.fringe_order, F_H, F_L, mask)
    continuous = side.model.predict(*(np.where(mask, a, 0).astype(np.float32) for a in (phases[0], wrapped_low, prior)),
                                    F_H)
    order = np.where(mask, np.rint(continuous), prior).astype(np.int32)
    return {"continuous": continuous, "order": order, "prior": prior, "mask": mask,
            "wrapped": np.where(mask, phases[0], 0.0), "psi_l": phases[1],
            "absolute": phases[0].astype(np.float64) + 2.0 * np.pi * order}


def timed(side: Side, inputs: dict) -> dict[str, float]:
    """One repeat of every part, CPU seconds each."""
    steps = {"floor": side.floor, "refine": side.refine_scan, "network_confidence": None,
             "frequency_consistency": None, "rejected_regions": None}
    seconds = {}
    for part, call in steps.items():
        if call is None:
            continue
        started = time.process_time()
        call()
        seconds[part] = time.process_time() - started
    confidence, consistency, regions = side.confidence, side.consistency, side.regions
    for part, run in (("network_confidence", lambda: confidence.network_confidence(
            inputs["continuous"], inputs["order"], inputs["prior"], inputs["mask"], wrapped_high=inputs["wrapped"])),
            ("frequency_consistency", lambda: consistency.frequency_consistency(
                inputs["absolute"], inputs["psi_l"], F_H, F_L, inputs["mask"], floor=side.out["floor"])),
            ("rejected_regions", lambda: regions.rejected_regions(inputs["absolute"], inputs["psi_l"], F_H, F_L,
                                                                  inputs["mask"]))):
        started = time.process_time()
        run()
        seconds[part] = time.process_time() - started
    return seconds


def side_by_side(base: str, source: str, size: str, repeats: int, consensus: bool) -> dict:
    """Both sides' outputs compared, then their parts timed alternately; the result's figures."""
    from dptpu.models.inference import shipped_model_path

    model_path = shipped_model_path()
    if model_path is None:
        raise ValueError("this build has no shipped model")
    maps = scan_maps(source, size)
    sides = {"base": Side(base, maps, model_path, consensus), "tree": Side("dptpu", maps, model_path, consensus)}
    inputs = part_inputs(sides["tree"])
    for side in sides.values():
        side.floor()
        side.refine_scan()
        side.parts(inputs)
    differing = [name for name, value in sides["tree"].out.items()
                 if not (value.dtype == sides["base"].out[name].dtype
                         and np.array_equal(value, sides["base"].out[name], equal_nan=True))]
    times: dict[str, list] = {name: [] for name in sides}
    for repeat in range(WARMUPS + repeats):
        order = ("base", "tree") if repeat % 2 else ("tree", "base")
        for name in order:
            seconds = timed(sides[name], inputs)
            if repeat >= WARMUPS:
                times[name].append(seconds)
    figures: dict = {}
    for part in PARTS:
        ms = {name: 1e3 * np.array([t[part] for t in times[name]]) for name in sides}
        figures[part] = {"base_ms_p50": round(float(np.median(ms["base"])), 2),
                         "base_ms_min": round(float(ms["base"].min()), 2),
                         "tree_ms_p50": round(float(np.median(ms["tree"])), 2),
                         "tree_ms_min": round(float(ms["tree"].min()), 2),
                         "paired_difference_ms_p50": round(float(np.median(ms["tree"] - ms["base"])), 2)}
    valid = maps["valid"]
    return {"source": source, "size": size, "consensus": consensus, "repeats": repeats,
            "valid_pixels": int(np.count_nonzero(valid)), "parts": figures, "outputs_differing": differing}


def _line(result: dict) -> str:
    parts = "; ".join(f"{part} {f['base_ms_p50']:.1f} -> {f['tree_ms_p50']:.1f} ms (min {f['base_ms_min']:.1f} -> "
                      f"{f['tree_ms_min']:.1f}, paired {f['paired_difference_ms_p50']:+.1f})"
                      for part, f in result["parts"].items())
    same = "outputs identical" if not result["outputs_differing"] else f"DIFFER: {result['outputs_differing']}"
    return f"DP-TPU unwrap path, consensus {'on' if result['consensus'] else 'off'}, {result['size']}: {parts}; {same}"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dptpu bench unwrap_dptpu", description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", default="6669a7e", help="git commit whose fpp and models are the base (default: "
                        "6669a7e, the tree before session 10's unwrap work)")
    parser.add_argument("--source", default="raycast", help="'raycast' (random-1 rendered as the sim node renders "
                        "it) or a folder of dptpu-capture/1 captures (its first)")
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--consensus", action="store_true", help="the neighbour consensus on (as dptpu unwrap)")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.repeats < 1:
        print(f"dptpu bench unwrap_dptpu: error: --repeats takes a positive count; got {args.repeats}",
              file=sys.stderr)
        return 2
    from dptpu.nodes.node_main import keep_freed_memory

    keep_freed_memory()  # as every node does: per-scan arrays reused without page faults
    with tempfile.TemporaryDirectory(prefix="dptpu-unwrap-base-") as folder:
        try:
            base = extract_base(args.base, Path(folder))
        except ValueError as exc:
            print(f"dptpu bench unwrap_dptpu: error: {exc}", file=sys.stderr)
            return 2
        sys.path.insert(0, folder)
        try:
            result = side_by_side(base, args.source, args.size, args.repeats, args.consensus)
        except ValueError as exc:
            print(f"dptpu bench unwrap_dptpu: error: {exc}", file=sys.stderr)
            return 2
        finally:
            sys.path.remove(folder)
    print(json.dumps({"base": args.base, **result}, indent=1) if args.json else _line(result))
    return 1 if result["outputs_differing"] else 0


if __name__ == "__main__":
    sys.exit(main())
