"""``dptpu eval cloud``: precision and completeness of the published points on rigs and scenes the model never saw,
and on the real CFPE captures (issue #16).

1. **Twin captures** (:func:`render_eval_captures`): crossing-axes rigs outside the training rigs (other camera focal
   lengths, baselines, toe-in angles and working distances: :data:`OUTSIDE_RIGS`), random scenes of several objects
   before a tilted background (:func:`dptpu.sim.scenes.random_scene`, a seed root no training set used), rendered by
   the raycast twin at ``supersample x supersample`` rays per pixel and box-averaged (a camera pixel integrates its
   area: mixed pixels at depth edges), with Gaussian camera noise of 0, 1 and 2 of the paper's sigma (1.5693 DN),
   12 steps and the paper's 3 steps, one capture holding the high frequency and the low one of every method
   (MF ``f_l = 1``, MW ``f_l = f_h - 1``, NT ``f_l`` = :data:`NT_LOW_FREQUENCY`).
2. **Each method and solver** (:func:`published_cloud`, what ``dptpu triangulate`` does with its defaults): the
   classical order (:func:`dptpu.fpp.reconstruct.unwrap_capture`) or DP-TPU's
   (:func:`dptpu.models.refine.refine_capture_result`, the model of ``--model``, on the methods it was trained
   for); the pixels whose confidence is below ``min_confidence`` dropped (:func:`dptpu.fpp.confidence.confident`);
   triangulation; the points at depth edges dropped (:func:`dptpu.fpp.depth_edges.edge_points`: flying points,
   the far side of depth steps, modulation dips at depth edges, partly shadowed points predicted more than 1 mm off,
   isolated points; ``edges=False`` keeps them) and the islands of a wrong order
   (:func:`dptpu.fpp.order_islands.order_islands`; ``islands=False`` keeps them). The published points are the
   finite ones left.
3. **Scores** (:func:`dptpu.fpp.cloud_accuracy.cloud_accuracy`, the scan monitor's definition): the share of
   published points with a wrong order or off the true surface, and the share of the truly valid pixels published,
   pooled over rigs and scenes.
4. **Real CFPE captures** (:func:`cfpe_rows`, ``../shared/data/cfpe``): 3-step inputs from steps 0, 4, 8 of the
   12-step frames, the three-period heterodyne (classical, = MF on the beat pair of
   :func:`dptpu.sim.diagnosis.cfpe_inputs.cfpe_pair`) and DP-TPU on that pair; reference: the 12-step heterodyne
   order. Published: pixels the reference holds whose order puts them on the projector; precision = the share at
   the reference order; completeness = published / pixels the reference holds. Each scene as captured and with the
   projector's response compensated (the 3-step harmonic phase error calibrated on the other scenes).

Outputs: ``cloud_eval.md`` (the table and the goals) and ``cloud_eval.json`` (every row, per capture and pooled).
"""
from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from itertools import product
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from dptpu.fpp import tpu
from dptpu.fpp.calibration import load_rig
from dptpu.fpp.capture import read_capture
from dptpu.fpp.cloud_accuracy import OFF_SURFACE_MM, cloud_accuracy, order_shift
from dptpu.fpp.confidence import DEFAULT_MIN_CONFIDENCE, confident
from dptpu.fpp.depth_edges import DEFAULT_MAX_EDGE_ERROR_MM, edge_points
from dptpu.fpp.order_islands import order_islands
from dptpu.fpp.reconstruct import CaptureResult, unwrap_capture
from dptpu.fpp.shadow_border import depth_per_pixel
from dptpu.fpp.triangulate import Triangulator, camera_depth, projector_coordinate
from dptpu.models.inference import FringeOrderModel
from dptpu.models.refine import refine_capture_result, refine_order_and_confidence
from dptpu.sim.diagnosis.cfpe_inputs import cfpe_pair, cfpe_phase_response
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.outside_rigs import OUTSIDE_RIGS, EvalRig
from dptpu.sim.render import render_capture
from dptpu.sim.rig import Rig
from dptpu.sim.scenes.random_scene import random_scene

__all__ = ["CFPE_SCENES", "GOALS", "NT_LOW_FREQUENCY", "OUTSIDE_RIGS", "PAPER_SIGMA_DN", "CloudEvalSpec", "EvalRig",
           "cfpe_rows", "format_table", "goal_checks", "pool_rows", "published_cloud", "render_eval_captures",
           "run_cloud_eval", "score_capture"]

#: The paper's 1 sigma camera noise, gray levels (2 sigma = 3.1386).
PAPER_SIGMA_DN = 1.5693
#: NT's low frequency (the paper's NT pairs: f_l = 10.9, not a divisor of f_h).
NT_LOW_FREQUENCY = 10.9
#: Scene seed root: the shipped model's training set used 100, its held-out set 200, ``dptpu eval unwrap`` 300.
DEFAULT_SEED = 500
CFPE_SCENES = ("01", "04", "06", "08")
#: The CFPE rows' projector response: the 3-step phases as captured, and compensated (:func:`cfpe_rows`).
RESPONSES = ("as captured", "compensated")
#: Issue #16's goals: largest wrong share and smallest completeness per capture kind.
GOALS = {"12-step": (0.0005, 0.97), "3-step 2 sigma": (0.001, 0.95), "cfpe": (0.005, float("nan"))}


@dataclass(frozen=True)
class CloudEvalSpec:
    """What ``dptpu eval cloud`` renders and scores (defaults: one tiny scene on one rig, seconds)."""

    rigs: tuple[EvalRig, ...] = OUTSIDE_RIGS[:1]
    scenes: int = 1
    size: tuple[int, int] = (96, 72)
    frequency: float = 16.0  # periods of about 9 camera pixels at 96x72 on the first rig (64 at 320x240: 7.4)
    steps: tuple[int, ...] = (12, 3)
    noise_sigmas: tuple[float, ...] = (0.0, 1.0, 2.0)
    methods: tuple[str, ...] = ("mf", "mw", "nt")
    supersample: int = 3
    seed: int = DEFAULT_SEED
    objects: tuple[int, int] = (2, 4)
    cfpe_scenes: tuple[str, ...] = ()
    off_surface_mm: float = OFF_SURFACE_MM
    min_confidence: float = DEFAULT_MIN_CONFIDENCE
    edges: bool = True  # drop the points at depth edges (dptpu triangulate's default)
    islands: bool = True  # drop the islands of a wrong fringe order (dptpu triangulate's default)

    def __post_init__(self):
        if not self.rigs or self.scenes < 1 or not self.steps or not self.noise_sigmas or not self.methods:
            raise ValueError("dptpu eval cloud needs at least one rig, scene, step count, noise level and method")
        if any(m not in ("mf", "mw", "nt") for m in self.methods):
            raise ValueError(f"methods must be among mf, mw, nt; got {', '.join(self.methods)}")
        if any(s < 3 for s in self.steps) or any(not s >= 0 for s in self.noise_sigmas):
            raise ValueError(f"steps must be >= 3 and noise sigmas >= 0; got {self.steps}, {self.noise_sigmas}")
        if not 0.0 <= self.min_confidence <= 1.0:
            raise ValueError(f"min_confidence must be in [0, 1]; got {self.min_confidence:g}")
        if not 16 <= self.frequency <= 120:
            raise ValueError(f"frequency must lie in 16..120 periods; got {self.frequency:g}")
        if any(s not in CFPE_SCENES for s in self.cfpe_scenes):
            raise ValueError(f"CFPE scenes are {', '.join(CFPE_SCENES)}; got {', '.join(self.cfpe_scenes)}")

    def low_frequency(self, method: str) -> float:
        return {"mf": 1.0, "mw": self.frequency - 1.0, "nt": NT_LOW_FREQUENCY}[method]


@dataclass
class CloudEvalResult:
    rows: list[dict]
    pooled: list[dict]
    cfpe: list[dict]
    goals: list[dict]
    table: str
    files: dict[str, Path] = field(default_factory=dict)


# -- twin captures -----------------------------------------------------------------------------------------------

def render_eval_captures(spec: CloudEvalSpec, out_dir, *, progress: bool = False) -> list[dict]:
    """Render every (rig, scene, steps, noise) capture of ``spec`` under ``out_dir``; their descriptions.

    ``progress``: a tqdm bar on stderr.
    """
    out_dir = Path(out_dir)
    captures = []
    lows = sorted({spec.low_frequency(m) for m in spec.methods}, reverse=True)
    total = len(spec.rigs) * spec.scenes * len(spec.steps) * len(spec.noise_sigmas)
    bar = tqdm(total=total, desc="rendering", unit="capture", disable=not progress, file=sys.stderr)
    for rig_index, eval_rig in enumerate(spec.rigs):
        rig = eval_rig.rig(spec.size)
        for scene_index in range(spec.scenes):
            scene_seed = spec.seed + 100 * rig_index + scene_index
            scene = random_scene(rig, scene_seed, objects=spec.objects, background_probability=1.0)
            for steps in spec.steps:
                sequences = [SequenceSpec(frequency=f, steps=steps) for f in (spec.frequency, *lows)]
                for sigma in spec.noise_sigmas:
                    effects = [{"name": "sensor_noise", "read_noise_dn": sigma * PAPER_SIGMA_DN,
                                "gain_dn_per_electron": 0.0}] if sigma > 0 else []
                    folder = out_dir / f"{eval_rig.name}_scene{scene_seed}_{steps}step_{sigma:g}sigma"
                    render_capture(rig, scene, sequences, folder, effects=effects,
                                   seed=scene_seed * 10 + steps + int(10 * sigma), supersample=spec.supersample)
                    captures.append({"folder": folder, "rig": eval_rig.name, "scene": scene_seed, "steps": steps,
                                     "noise_sigma": sigma})
                    bar.update()
    bar.close()
    return captures


def published_cloud(result: CaptureResult, rig: Rig, extent_px: int, axis: str, *,
                    min_confidence: float = DEFAULT_MIN_CONFIDENCE, edges: bool = True,
                    islands: bool = True) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """``(published (H, W) bool, depth (H, W), dropped counts)`` of an unwrapped capture, as ``dptpu triangulate``
    publishes it: the valid pixels of at least ``min_confidence`` triangulated, the finite points kept but those at
    depth edges (``edges``) and those on islands of a wrong order (``islands``, :func:`dptpu.fpp.order_islands.
    order_islands`); depth = camera ``z`` in the rig's units, NaN where nothing is published. ``dropped``:
    ``{"low_confidence": n, "edges": n, "islands": n}``."""
    valid, low_confidence = confident(result.reliability, result.valid, min_confidence)
    x_p = projector_coordinate(np.where(valid, result.absolute_phase, np.nan), result.frequency, extent_px)
    triangulator = Triangulator(rig, axis=axis)

    def depth_at(projector_x: np.ndarray, pixels: np.ndarray) -> np.ndarray:  # the few pixels asked for
        return camera_depth(triangulator.points(projector_x, pixels=pixels), rig.camera)

    def per_px(where: np.ndarray) -> np.ndarray:  # the second triangulation, where edge_points needs it
        return depth_per_pixel(x_p, depth_at, axis, depth=depth, where=where)

    depth = camera_depth(triangulator.points(x_p), rig.camera)  # (H, W), NaN where no point
    published = np.isfinite(depth)
    at_edges = 0
    if edges:
        focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])
        max_error = DEFAULT_MAX_EDGE_ERROR_MM / {"mm": 1.0, "m": 1e3}.get(rig.units, 1.0)
        dropped = edge_points(depth, focal_px, result.modulation, lit=result.valid, depth_per_px=per_px,
                              max_edge_error=max_error, axis=axis).dropped & published
        at_edges = int(np.count_nonzero(dropped))
        published &= ~dropped
    on_islands = 0
    if islands:
        island = order_islands(result.absolute_phase, result.modulation, valid).islands & published
        on_islands = int(np.count_nonzero(island))
        published &= ~island
    depth = np.where(published, depth, np.nan)
    return published, depth, {"low_confidence": low_confidence, "edges": at_edges, "islands": on_islands}


Publisher = Callable[..., tuple[np.ndarray, np.ndarray, dict[str, int]]]


def score_capture(capture: dict, spec: CloudEvalSpec, models: Iterable[FringeOrderModel] = (),
                  publish: Publisher = published_cloud) -> list[dict]:
    """One row per method and solver (``classical`` and each model serving the method) of one rendered capture."""
    folder = Path(capture["folder"])
    loaded = read_capture(folder)
    if loaded.calibration is None:
        raise ValueError(f"{folder}: the rendered capture has no calibration")
    rig = load_rig(loaded.calibration)
    truth = np.load(folder / "gt.npz")
    truly_valid = np.asarray(truth["valid"], bool)
    extent = loaded.fringe_extent_px
    truth_phase = 2.0 * np.pi * spec.frequency * np.asarray(truth["projector_x"], np.float64) / extent
    truth_depth = np.asarray(truth["depth"], np.float64)
    scale_to_mm = {"mm": 1.0, "m": 1e3}.get(rig.units, 1.0)
    rows = []
    for method in spec.methods:
        classical = unwrap_capture(loaded, method=method, high=spec.frequency, low=spec.low_frequency(method))
        solvers: list[tuple[str, CaptureResult]] = [("classical", classical)]
        for model in models:
            if model.serves(method):
                solvers.append(("dptpu" if model.kind == "dptpu" else model.kind,
                                refine_capture_result(classical, model)))
        for solver, result in solvers:
            published, depth, dropped = publish(result, rig, extent, loaded.fringe_axis,
                                                min_confidence=spec.min_confidence, edges=spec.edges,
                                                islands=spec.islands)
            accuracy = cloud_accuracy(published, truly_valid,
                                      shift=np.where(truly_valid, order_shift(result.absolute_phase, truth_phase),
                                                     np.nan),
                                      depth=depth * scale_to_mm, truth_depth=truth_depth * scale_to_mm,
                                      off_surface=spec.off_surface_mm)
            rows.append({"rig": capture["rig"], "scene": capture["scene"], "steps": capture["steps"],
                         "noise_sigma": capture["noise_sigma"], "method": method, "solver": solver,
                         **accuracy.as_dict(), "dropped_low_confidence": dropped["low_confidence"],
                         "dropped_at_edges": dropped["edges"], "dropped_on_islands": dropped["islands"]})
    return rows


def pool_rows(rows: list[dict]) -> list[dict]:
    """Rows pooled over rigs and scenes per (steps, noise, method, solver): counts summed, shares recomputed."""
    pooled: dict[tuple, dict] = {}
    for row in rows:
        key = (row["steps"], row["noise_sigma"], row["method"], row["solver"])
        entry = pooled.setdefault(key, {"steps": key[0], "noise_sigma": key[1], "method": key[2], "solver": key[3],
                                        "captures": 0, "published": 0, "truly_valid": 0, "published_truly_valid": 0,
                                        "wrong": 0, "wrong_order": 0, "off_surface": 0, "dropped_low_confidence": 0,
                                        "dropped_at_edges": 0, "dropped_on_islands": 0})
        entry["captures"] += 1
        for name in ("published", "truly_valid", "published_truly_valid", "wrong", "wrong_order", "off_surface",
                     "dropped_low_confidence", "dropped_at_edges", "dropped_on_islands"):
            entry[name] += row[name]
    for entry in pooled.values():
        entry["wrong_share"] = entry["wrong"] / entry["published"] if entry["published"] else float("nan")
        entry["completeness"] = (entry["published_truly_valid"] / entry["truly_valid"] if entry["truly_valid"]
                                 else float("nan"))
    return sorted(pooled.values(), key=lambda e: (-e["steps"], e["noise_sigma"], e["method"], e["solver"]))


# -- real CFPE ---------------------------------------------------------------------------------------------------

def cfpe_rows(cfpe_dir, scenes: Iterable[str], models: Iterable[FringeOrderModel] = (), *,
              min_confidence: float = DEFAULT_MIN_CONFIDENCE) -> list[dict]:
    """Per CFPE scene, projector response and solver: published pixels, the share at the 12-step reference order,
    completeness.

    Each scene twice: its 3-step phases as captured, and with the projector's response compensated as a user's
    scanner compensates it: ``dptpu calibrate response`` on the capture folders of the OTHER CFPE scenes
    (:func:`dptpu.sim.diagnosis.cfpe_inputs.cfpe_phase_response`: a calibration of the projector, never of the
    scene scored), applied as every phase computation of a rig with ``projector.phase_response`` applies it
    (:meth:`dptpu.fpp.phase_harmonics.ProjectorPhaseResponse.correct`). The pixels of a confidence below
    ``min_confidence`` are not published (classical: the MF rounding margin of the beat pair,
    :func:`dptpu.fpp.tpu.unwrap_mf`; DP-TPU: the network's confidence). No calibration ships with CFPE: no depth,
    so no depth-edge filter, no islands (no modulation in the pair) and no off-surface test; only the order counts.
    """
    rows = []
    models = list(models)
    for scene, response in product(scenes, RESPONSES):
        calibrated = (cfpe_phase_response(cfpe_dir, [s for s in CFPE_SCENES if s != scene])
                      if response == "compensated" else None)
        pair = cfpe_pair(cfpe_dir, scene, phase_error=calibrated)
        phase_error = None if calibrated is None else calibrated.for_steps(3)
        classical = tpu.unwrap_mf(pair.wrapped_high, pair.wrapped_low, pair.frequency_high, pair.frequency_low,
                                  valid=pair.valid)
        solvers = [("classical", np.asarray(pair.coarse_order), np.asarray(classical.reliability))]
        for model in models:
            if model.serves("mf"):
                order, confidence = refine_order_and_confidence(
                    model, "mf", pair.wrapped_high, pair.wrapped_low, pair.coarse_order, pair.frequency_high,
                    pair.frequency_low, pair.valid)
                solvers.append(("dptpu" if model.kind == "dptpu" else model.kind, order, confidence))
        for solver, order, confidence in solvers:
            phase = pair.absolute_phase(order)
            with np.errstate(invalid="ignore"):
                on_projector = pair.valid & (phase >= 0) & (phase < 2 * np.pi * pair.frequency_high)
            published, _ = confident(confidence, on_projector, min_confidence)
            accuracy = cloud_accuracy(published, pair.valid,
                                      shift=np.where(pair.valid, np.asarray(order) - pair.reference_order, np.nan))
            rows.append({"scene": scene, "response": response, "solver": solver,
                         "method": "heterodyne 3-step (MF on the beat pair)", **accuracy.as_dict(),
                         "at_reference": 1.0 - accuracy.wrong_share,
                         "phase_error_rad": None if phase_error is None else phase_error.amplitude_rad})
    return rows


# -- report ------------------------------------------------------------------------------------------------------

def _goal_of(entry: dict) -> tuple[str, float, float] | None:
    if entry["steps"] >= 12:
        return ("12-step", *GOALS["12-step"])
    if entry["steps"] == 3 and entry["noise_sigma"] == 2.0:
        return ("3-step 2 sigma", *GOALS["3-step 2 sigma"])
    return None


def goal_checks(pooled: list[dict], cfpe: list[dict]) -> list[dict]:
    """Each pooled row with a goal (12-step; 3-step at 2 sigma) and each CFPE row against issue #16's goals."""
    checks = []
    for entry in pooled:
        goal = _goal_of(entry)
        if goal is None:
            continue
        name, max_wrong, min_complete = goal
        checks.append({"goal": name, "steps": entry["steps"], "noise_sigma": entry["noise_sigma"],
                       "method": entry["method"], "solver": entry["solver"], "wrong_share": entry["wrong_share"],
                       "completeness": entry["completeness"],
                       "met": bool(entry["wrong_share"] <= max_wrong and entry["completeness"] >= min_complete)})
    for row in cfpe:
        checks.append({"goal": "cfpe", "scene": row["scene"], "response": row["response"], "solver": row["solver"],
                       "wrong_share": row["wrong_share"], "completeness": row["completeness"],
                       "met": bool(row["wrong_share"] <= GOALS["cfpe"][0])})
    return checks


def _percent(value: float, digits: int) -> str:
    return "n/a" if not math.isfinite(value) else f"{100 * value:.{digits}f}"


def format_table(pooled: list[dict], cfpe: list[dict], spec: CloudEvalSpec) -> str:
    """The markdown report: the twin table (wrong % / complete % per solver) and the CFPE table."""
    solvers = sorted({e["solver"] for e in pooled}, key=lambda s: (s != "classical", s))
    lines = [f"Twin captures: {len(spec.rigs)} rig(s) ({', '.join(r.name for r in spec.rigs)}), {spec.scenes} "
             f"scene(s) each, {spec.size[0]}x{spec.size[1]}, f_h = {spec.frequency:g}, {spec.supersample}x"
             f"{spec.supersample} supersampling; wrong = wrong order or more than max({spec.off_surface_mm:g} mm, "
             "6 sigma) off the true depth, per published point; complete = published / truly valid pixels. "
             f"Published as `dptpu triangulate` does: confidence >= {spec.min_confidence:g}, "
             + ("points at depth edges dropped" if spec.edges else "points at depth edges kept")
             + (", islands of a wrong order dropped." if spec.islands else ", islands of a wrong order kept."), "",
             "| steps | noise | method | " + " | ".join(f"{s} wrong % | {s} complete %" for s in solvers) + " |",
             "|---|---|---|" + "---|---|" * len(solvers)]
    by_key: dict[tuple, dict[str, dict]] = {}
    for entry in pooled:
        by_key.setdefault((entry["steps"], entry["noise_sigma"], entry["method"]), {})[entry["solver"]] = entry
    for (steps, sigma, method), entries in by_key.items():
        cells = []
        for solver in solvers:
            found = entries.get(solver)
            cells += ["-", "-"] if found is None else [_percent(found["wrong_share"], 3),
                                                       _percent(found["completeness"], 2)]
        lines.append(f"| {steps} | {sigma:g} sigma | {method} | " + " | ".join(cells) + " |")
    if cfpe:
        lines += ["", "Real CFPE captures (3-step from the 12-step frames; reference: the 12-step heterodyne order; "
                  "projector response as captured, or compensated by the harmonic phase error fitted on the other "
                  "scenes):", "", "| scene | response | solver | published | at reference order % | completeness % |",
                  "|---|---|---|---|---|---|"]
        for row in cfpe:
            lines.append(f"| {row['scene']} | {row['response']} | {row['solver']} | {row['published']:,} | "
                         f"{_percent(row['at_reference'], 3)} | {_percent(row['completeness'], 2)} |")
    return "\n".join(lines) + "\n"


def _json_ready(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def run_cloud_eval(spec: CloudEvalSpec, out_dir, *, models: Iterable[FringeOrderModel] = (), cfpe_dir=None,
                   command: str = "", progress: bool = False) -> CloudEvalResult:
    """Render, score and write ``cloud_eval.md`` and ``cloud_eval.json`` to ``out_dir`` (``progress``: tqdm bars on
    stderr)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    models = list(models)
    rows = []
    captures = render_eval_captures(spec, out_dir / "captures", progress=progress)
    for capture in tqdm(captures, desc="scoring", unit="capture", disable=not progress, file=sys.stderr):
        rows += score_capture(capture, spec, models)
    pooled = pool_rows(rows)
    cfpe = []
    if cfpe_dir is not None and spec.cfpe_scenes:
        cfpe = cfpe_rows(cfpe_dir, spec.cfpe_scenes, models, min_confidence=spec.min_confidence)
    goals = goal_checks(pooled, cfpe)
    table = format_table(pooled, cfpe, spec)
    met = sum(g["met"] for g in goals)
    report = table + f"\nGoals of issue #16 met: {met} of {len(goals)}" + "".join(
        f"\n- not met: {g['goal']} {g.get('method', g.get('scene', ''))} {g['solver']}: "
        f"{_percent(g['wrong_share'], 3)} % wrong, {_percent(g['completeness'], 2)} % complete"
        for g in goals if not g["met"]) + "\n"
    if command:
        report = f"Command: `{command}`\n\n" + report
    files = {"table": out_dir / "cloud_eval.md", "json": out_dir / "cloud_eval.json"}
    files["table"].write_text(report)
    spec_dict: dict[str, Any] = {**asdict(spec), "rigs": [asdict(r) for r in spec.rigs]}
    files["json"].write_text(json.dumps(_json_ready({"command": command, "spec": spec_dict, "pooled": pooled,
                                                     "cfpe": cfpe, "goals": goals, "rows": rows}), indent=1))
    return CloudEvalResult(rows=rows, pooled=pooled, cfpe=cfpe, goals=goals, table=report, files=files)
