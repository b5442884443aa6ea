"""``dptpu bench floor_kernels``: the floor's per-scan kernels of ``fpp`` at a base commit against the working tree's,
side by side in one process, outputs compared bit for bit (not a test).

The pipeline floor (``dptpu bench pipeline --floor``, :func:`pipeline_bench.floor_ms_per_scan`) times the work of
a scan in one process; this bench times the same five parts (``phase``: the sums of Eq. (2), the float32
arctangent, the modulation and saturation mask and the phase-noise test of entries of 5 or more steps; ``unwrap``:
Eq. (5), ``unwrap_mf_float32``; ``triangulate``: the float32 camera points with both lens distortions;
``filters``: ``edge_points`` with the partly shadowed points' second triangulation and ``order_islands``, the
dropped points blanked; ``assemble``: confidence, normals and the (H, W, 9) cloud) twice, once with the ``fpp``
package of ``--base`` (taken from git with ``git archive`` into a temporary folder and imported under another
name) and once with the installed one, on the same frames, alternating the two every repeat (the machine's other
load falls on both alike), and reports each part's median CPU time (``time.process_time``, every thread) after
:data:`WARMUPS` untimed repeats.

Before timing it runs both once and compares every output bit for bit: the wrapped phase, modulation and
background of both sequences, the valid mask, the phase-noise maps, the absolute phase, the projector coordinate,
each reason's mask of the dropped edge points, the islands and the (H, W, 9) cloud. The phase maps are compared as
computed; OpenCV's magnitude and angle round 1 ulp apart on other memory alignment (:func:`dptpu.fpp.phase.
sequence_sums`), so the base's maps feed both sides' later parts and the noise test. A difference is reported
(``outputs_differing``) and makes the exit code 1.

Each side blanks the dropped points as its own tree's floor does: ``--base`` with ``planes[:, mask] = nan`` when its
``fpp`` predates ``fringe_noise.sequence_phase_noise`` (before session 10), the working tree by a masked copy a
plane (as the cloud node does). Run from a source checkout (git)::

    dptpu bench floor_kernels [--base b829bd7] [--steps 3,12] [--source FOLDER|raycast] [--size 640x480]
                              [--repeats 30] [--json]

Results: docs/benchmarks.md, "Floor kernels, session 10".
"""
from __future__ import annotations

import argparse
import importlib
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
SHIPPED_RIG = REPO_ROOT / "launch" / "params" / "shipped_rig.yaml"
SEQUENCES = {12: "64x12,1x12", 3: "64x3,1x3"}
#: The scene the graph scans first (the pipeline bench's first raycast scene).
FIRST_SCENE = "random:1"
#: The name the base's ``fpp`` is imported under.
BASE_PACKAGE = "dptpu_floor_base_fpp"
PARTS = ("phase", "unwrap", "triangulate", "filters", "assemble")
#: Untimed repeats a side first (as the pipeline floor's ``FLOOR_WARMUPS``): the heap grows to what a scan needs
#: (with two, the step count measured first ran 20-30 % slower than the same work measured second).
WARMUPS = 10


def extract_base(commit: str, folder: Path) -> str:
    """``git archive`` the ``fpp`` folder of ``commit`` into ``folder/BASE_PACKAGE``; the package name."""
    archive = subprocess.run(["git", "-C", str(REPO_ROOT), "archive", commit, "fpp"], capture_output=True,
                             check=False)
    if archive.returncode != 0:
        raise ValueError(f"git archive {commit} fpp failed: {archive.stderr.decode(errors='replace').strip()}")
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    (folder / "fpp").rename(folder / BASE_PACKAGE)
    return BASE_PACKAGE


def kernels(package: str) -> dict:
    """The floor's kernel modules of one ``fpp`` package (``dptpu.fpp`` or the base's)."""
    def module(name: str):
        return importlib.import_module(f"{package}.{name}")

    found = {name: module(name) for name in ("phase", "tpu", "fringe_noise", "depth_edges", "order_islands",
                                             "organized_normals", "triangulate")}
    edges = found["depth_edges"]
    found["depth_per_pixel"] = getattr(edges, "depth_per_pixel", None) or module("shadow_border").depth_per_pixel
    return found


def load_frames(steps: int, source: str, size: str):
    """``(stacks, rig)``: the two (N, H, W) uint8 sequences of the graph's first scene, as the floor loads them."""
    from dptpu.nodes.sim.source import load_source

    loaded = load_source(source, rig=str(SHIPPED_RIG), size=size, scenes=FIRST_SCENE, sequence=SEQUENCES[steps])
    stacks = [loaded.scenes[0].stack(frequency, steps) for frequency in (64.0, 1.0)]
    if any(stack is None for stack in stacks):
        raise ValueError(f"the first scene of {source} holds no 64x{steps} and 1x{steps} sequences")
    return [np.ascontiguousarray(stack) for stack in stacks], loaded.rig


class FloorParts:
    """The floor's five parts of one scan with one ``fpp`` package, their state kept between parts."""

    def __init__(self, package: str, stacks: list[np.ndarray], rig, *, masked_blank: bool) -> None:
        self.k, self.stacks, self.rig, self.masked_blank = kernels(package), stacks, rig, masked_blank
        self.steps = stacks[0].shape[0]
        self.extent = rig.projector.size[0]
        self.triangulator = self.k["triangulate"].Triangulator(rig, axis="x")
        self.focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])
        self.state: dict = {}

    def phase(self) -> None:
        phase = self.k["phase"]
        maps = [phase.maps_from_sums(phase.sequence_sums(stack)) for stack in self.stacks]
        valid = np.ones(self.stacks[0].shape[1:], dtype=bool)
        for m in maps:
            valid &= m.modulation >= 10.0
        valid &= np.maximum.reduce([stack.max(axis=0) for stack in self.stacks]) < 255
        self.state["maps"], self.state["mask"] = maps, valid
        self.noise_test()

    def noise_test(self) -> None:
        noise, maps, valid = self.k["fringe_noise"], self.state["maps"], self.state["mask"].copy()
        if hasattr(noise, "sequence_phase_noise"):
            sigma, floors = zip(*(noise.sequence_phase_noise(stack, m.background, m.modulation)
                                  for stack, m in zip(self.stacks, maps)))
        else:  # the three calls each caller made before sequence_phase_noise
            sigma = [noise.phase_noise(noise.fit_residual(stack, m.background, m.modulation), m.modulation,
                                       self.steps) for stack, m in zip(self.stacks, maps)]
            floors = [noise.quantization_phase_noise(m.modulation, self.steps, stack.dtype)
                      for stack, m in zip(self.stacks, maps)]
        valid &= ~noise.noise_outliers(sigma, valid, noise.DEFAULT_MAX_NOISE_RATIO, floors)
        self.state["noise"], self.state["valid"] = sigma, valid

    def unwrap(self) -> None:
        maps = self.state["maps"]
        self.state["unwrapped"] = self.k["tpu"].unwrap_mf_float32(maps[0].phase, maps[1].phase, 64.0, 1.0,
                                                                  valid=self.state["valid"])

    def triangulate(self) -> None:
        result = self.state["unwrapped"]
        coord = self.state["coord"] = self.k["triangulate"].projector_coordinate(result.absolute_phase, 64.0,
                                                                                 self.extent)
        planes = self.state["planes"] = np.empty((3, *coord.shape), dtype=np.float32)
        self.triangulator.camera_points(coord, scale=self.rig.scale_to_m, dtype=np.float32,
                                        out=planes.transpose(1, 2, 0))

    def filters(self) -> None:
        state, k = self.state, self.k
        planes, result, modulation = state["planes"], state["unwrapped"], state["maps"][0].modulation
        depth = planes[2]

        def depth_at(projector_x, pixels):
            return self.triangulator.camera_points(projector_x, scale=self.rig.scale_to_m, dtype=np.float32,
                                                   pixels=pixels)[:, 2]

        def per_px(where):
            return k["depth_per_pixel"](state["coord"], depth_at, "x", depth=depth, where=where)

        edges = k["depth_edges"].edge_points(depth, self.focal_px, modulation, lit=result.valid,
                                             depth_per_px=per_px,
                                             max_edge_error=k["depth_edges"].DEFAULT_MAX_EDGE_ERROR_MM * 1e-3,
                                             axis="x")
        islands = k["order_islands"].order_islands(result.absolute_phase, modulation, result.valid)
        dropped = edges.dropped | islands.islands
        if self.masked_blank:
            for plane in planes:
                np.copyto(plane, np.float32(np.nan), where=dropped)
        else:
            planes[:, dropped] = np.nan
        state["edges"], state["islands"] = edges, islands

    def assemble(self) -> None:
        import cv2

        state = self.state
        planes = state["planes"]
        confidence = np.where(np.isfinite(planes[2]), state["unwrapped"].reliability,
                              np.float32(0.0)).astype(np.float32, copy=False)
        normals = np.empty_like(planes)
        self.k["organized_normals"].organized_normals(planes.transpose(1, 2, 0), out=normals.transpose(1, 2, 0))
        state["cloud"] = cv2.merge([*planes, state["maps"][0].background, state["maps"][0].modulation, confidence,
                                    *normals])

    def outputs(self) -> dict[str, np.ndarray]:
        state = self.state
        out = {"valid": state["valid"], "absolute_phase": state["unwrapped"].absolute_phase,
               "reliability": state["unwrapped"].reliability, "coord": state["coord"], "cloud": state["cloud"],
               "islands": state["islands"].islands}
        for reason in ("flying", "beside_step", "modulation_dip", "isolated", "shadow_border"):
            out[f"edges.{reason}"] = getattr(state["edges"], reason)
        for index, sigma in enumerate(state["noise"]):
            if sigma is not None:
                out[f"noise{index}"] = sigma
        return out


def _maps(parts: FloorParts) -> dict[str, np.ndarray]:
    return {f"{name}{index}": getattr(m, name) for index, m in enumerate(parts.state["maps"])
            for name in ("phase", "modulation", "background")}


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


def side_by_side(base: str, steps: int, source: str, size: str, repeats: int) -> dict:
    """Both packages' parts on the same frames: the outputs compared, then ``repeats`` alternated timings."""
    stacks, rig = load_frames(steps, source, size)
    sides = {"base": FloorParts(base, stacks, rig, masked_blank=False), "tree": FloorParts("dptpu.fpp", stacks, rig,
                                                                                          masked_blank=True)}
    base_uses_new_noise = hasattr(sides["base"].k["fringe_noise"], "sequence_phase_noise")
    sides["base"].masked_blank = base_uses_new_noise
    for parts in sides.values():
        for name in PARTS:
            getattr(parts, name)()
    base_maps, tree_maps = _maps(sides["base"]), _maps(sides["tree"])
    phase_as_computed = [name for name in base_maps if not _same(base_maps[name], tree_maps[name])]
    tree = sides["tree"]  # the later parts again on the base's phase maps and mask
    tree.state["maps"], tree.state["mask"] = sides["base"].state["maps"], sides["base"].state["mask"]
    tree.noise_test()
    for name in PARTS[1:]:
        getattr(tree, name)()
    base_out, tree_out = sides["base"].outputs(), tree.outputs()
    differing = sorted(name for name in base_out.keys() | tree_out.keys()
                       if name not in base_out or name not in tree_out or not _same(base_out[name], tree_out[name]))
    times: dict[str, dict[str, list[float]]] = {side: {name: [] for name in PARTS} for side in sides}
    for repeat in range(repeats + WARMUPS):
        for side in (("base", "tree") if repeat % 2 == 0 else ("tree", "base")):
            for name in PARTS:
                started = time.process_time()
                getattr(sides[side], name)()
                times[side][name].append(time.process_time() - started)
    medians = {side: {name: round(1e3 * float(np.median(values[WARMUPS:])), 2) for name, values in parts.items()}
               for side, parts in times.items()}
    for figures in medians.values():
        figures["total"] = round(sum(figures[name] for name in PARTS), 2)
    edges = sides["tree"].state["edges"]
    return {"steps": steps, "frames": 2 * steps, "size": size, "source": source, "repeats": repeats,
            "base_ms": medians["base"], "tree_ms": medians["tree"],
            "phase_maps_differing_as_computed": phase_as_computed, "outputs_differing": differing,
            "valid_pixels": int(np.count_nonzero(sides["tree"].state["valid"])),
            "dropped": {reason: int(np.count_nonzero(getattr(edges, reason)))
                        for reason in ("flying", "beside_step", "modulation_dip", "isolated", "shadow_border")}
            | {"islands": int(np.count_nonzero(sides["tree"].state["islands"].islands))}}


def _line(result: dict) -> str:
    base, tree = result["base_ms"], result["tree_ms"]
    parts = ", ".join(f"{name} {base[name]:.2f} -> {tree[name]:.2f}" for name in PARTS)
    same = "outputs bit for bit the same" if not result["outputs_differing"] else \
        f"OUTPUTS DIFFER: {', '.join(result['outputs_differing'])}"
    return (f"2 x {result['steps']}-step: {base['total']:.2f} -> {tree['total']:.2f} ms CPU a scan ({parts}); "
            f"{same}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dptpu bench floor_kernels", description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", default="b829bd7", help="git commit whose fpp is the base (default: b829bd7, "
                        "the tree before session 10's floor work)")
    parser.add_argument("--steps", default="3,12", help="comma-separated steps per sequence (3 and/or 12)")
    parser.add_argument("--source", default="raycast", help="'raycast' (random-1 rendered as the sim node renders "
                        "it) or a folder of dptpu-capture/1 captures (its first)")
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--json", action="store_true", help="print the results as one JSON object")
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        steps = [int(s) for s in args.steps.split(",")]
        if any(s not in SEQUENCES for s in steps) or args.repeats < 1:
            raise ValueError
    except ValueError:
        print(f"dptpu bench floor_kernels: error: --steps takes 3 and/or 12 and --repeats a positive count; got "
              f"{args.steps!r}, {args.repeats}", file=sys.stderr)
        return 2
    from dptpu.nodes.node_main import keep_freed_memory

    keep_freed_memory()  # as every node does (and the pipeline floor): per-scan arrays reused without page faults
    with tempfile.TemporaryDirectory(prefix="dptpu-floor-base-") as folder:
        try:
            base = extract_base(args.base, Path(folder))
        except ValueError as exc:
            print(f"dptpu bench floor_kernels: error: {exc}", file=sys.stderr)
            return 2
        sys.path.insert(0, folder)
        try:
            results = [side_by_side(base, s, args.source, args.size, args.repeats) for s in steps]
        finally:
            sys.path.remove(folder)
    print(json.dumps({"base": args.base, "results": results}, indent=1) if args.json
          else "\n".join(_line(r) for r in results))
    return 1 if any(r["outputs_differing"] for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
