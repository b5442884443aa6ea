"""Downstream gain of an extended twin: fine-tune DP-TPU on it and on the baseline twin, score both on measured data.

``dptpu twin finetune --measured PATH --extended RIG --model BASE.onnx --out DIR`` (docs/sim-to-real.md,
"Downstream gain"):

1. **Measured pairs** (:mod:`dptpu.sim.diagnosis.cfpe_inputs`, :mod:`dptpu.sim.diagnosis.sphere_inputs`): the
   network's inputs built from the measured data, a reference order from a 12-step measurement, and what is real
   and what is synthesized. CFPE by default as a cascade (:mod:`dptpu.sim.diagnosis.beat_cascade`): its
   three-frequency heterodyne as two MF pairs, every solver applied level by level (:func:`cascade_orders`).
2. **Two twin sets of the same scenes** (:mod:`dptpu.sim.diagnosis.twin_pairs`): the baseline rig (the extended rig
   without its effects) and the extended rig, rendered with the measured data's sequences and pair construction; the
   sets differ only by the effects.
3. **Two fine-tunes with the same budget** (:mod:`.finetune`) from the base model's weights: the fine-tune on the
   baseline twin is the control, so a difference between the two is the extension's, not the extra steps'.
4. **Evaluation** (:func:`solver_orders`, :func:`evaluate_orders`): fringe-order accuracy of the classical order,
   the base model and both fine-tunes on every measured pair (and on held-out scenes of both twins), each solver
   scored twice and the same way: its order as it decides it (``accuracy``; the networks through the unwrap
   node's path, :func:`dptpu.models.refine.refine_order_and_confidence` without the vote) and after the same
   neighbour vote (``accuracy_vote``: :func:`dptpu.models.consensus.consensus_order`, which needs no network and
   is applied to the classical order too). CFPE is scored as captured and with the projector's response
   compensated (calibrated on the other scenes, :func:`dptpu.sim.diagnosis.cfpe_inputs.cfpe_phase_error`); for
   the sphere the 3D error of each order map (:func:`dptpu.sim.diagnosis.sphere_inputs.sphere_errors_um`).
   ``downstream.json`` and a "Downstream gain" section of ``report.md``.

``--extended cfpe-response`` (CFPE only) is the extension that carries the real projector's response: the
``projector_gamma`` whose rendered 3-step phase error equals the one measured on the real frames
(:mod:`dptpu.sim.diagnosis.cfpe_response`); the report checks both twins' rendered error against the measured one
(``response_check``).
"""
from __future__ import annotations

import copy
import json
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from tqdm import tqdm

from dptpu.fpp import real_sphere
from dptpu.fpp.dataset import list_samples, read_sample
from dptpu.models.consensus import consensus_order
from dptpu.models.inference import FringeOrderModel
from dptpu.models.refine import refine_order_and_confidence
from dptpu.sim.diagnosis.beat_cascade import CascadePair
from dptpu.sim.diagnosis.cfpe_inputs import LOW_PHASES, cfpe_cascade, cfpe_pair, cfpe_phase_error
from dptpu.sim.diagnosis.cfpe_response import cfpe_response_effects, cfpe_twin_rig, rendered_phase_error
from dptpu.sim.diagnosis.measured_pair import MeasuredPair, order_accuracy
from dptpu.sim.diagnosis.sphere_inputs import sphere_errors_um, sphere_pair, twin_levels
from dptpu.sim.diagnosis.twin_pairs import CASCADE, CFPE_DESIGN, SPHERE_DESIGN, twin_cascades, write_twin_set
from dptpu.sim.effects import parse_effects
from dptpu.sim.rig import load_twin_rig, resize_camera

from .finetune import FinetuneOptions, finetune, load_start_model

__all__ = ["DownstreamOptions", "measured_kind", "measured_pairs", "split_rigs", "evaluate_orders", "solver_orders",
           "run_downstream", "compare_finetunes", "twin_set_pairs", "write_downstream_report", "SIGMAS",
           "CFPE_RESPONSE", "RESPONSES"]

#: The paper's camera noise levels, DN (1 sigma, 2 sigma).
SIGMAS = (1.5693, 3.1386)
MODEL_NAMES = ("base", "finetuned_baseline", "finetuned_extended")
#: ``--extended`` value for the CFPE projector's response (:mod:`dptpu.sim.diagnosis.cfpe_response`).
CFPE_RESPONSE = "cfpe-response"
#: The CFPE pairs' projector response: the 3-step phases as captured, and compensated (calibrated on the other
#: scenes, as ``dptpu eval cloud`` does).
RESPONSES = ("captured", "compensated")


@dataclass(frozen=True)
class DownstreamOptions:
    """Sizes of a downstream run.

    Attributes
    ----------
    scenes : int
        Random twin scenes per training set (each at every ``noise`` level).
    size : (int, int)
        Camera ``(width, height)`` of the twin samples.
    noise : tuple of float
        Camera noise of the twin inputs, DN.
    seed : int
        Scenes, noise draws, crops.
    heldout_scenes : int
        Extra twin scenes (other seeds) to check what each model learned on both twins.
    cfpe_scenes : tuple of str
        CFPE scenes scored.
    cfpe_low : str
        ``cascade`` (default): CFPE's heterodyne as two MF pairs, every solver applied at each level
        (:mod:`dptpu.sim.diagnosis.beat_cascade`); or the low phase of one CFPE pair, ``het12`` / ``beat123``
        (:func:`dptpu.sim.diagnosis.cfpe_inputs.low_phase`), the solvers at the top level only.
    cfpe_responses : tuple of str
        CFPE pairs scored: ``captured`` and/or ``compensated`` (:data:`RESPONSES`).
    max_correction : int or None
        Training labels kept only within this many orders of the classical order (``PairDesign.max_correction``);
        ``-1`` (default): the design's.
    finetune : FinetuneOptions
    """

    scenes: int = 8
    size: tuple = (320, 240)
    noise: tuple = SIGMAS
    seed: int = 0
    heldout_scenes: int = 1
    cfpe_scenes: tuple = ("01", "04", "06", "08")
    cfpe_low: str = CASCADE
    cfpe_responses: tuple = RESPONSES
    max_correction: int | None = -1
    finetune: FinetuneOptions = field(default_factory=FinetuneOptions)

    def __post_init__(self):
        if self.cfpe_low not in (CASCADE, *LOW_PHASES):
            raise ValueError(f"--cfpe-low must be one of {', '.join((CASCADE, *LOW_PHASES))}; got {self.cfpe_low!r}")
        if not self.cfpe_responses or any(r not in RESPONSES for r in self.cfpe_responses):
            raise ValueError(f"CFPE responses must be among {', '.join(RESPONSES)}; got {list(self.cfpe_responses)}")


def measured_kind(path) -> str:
    """``cfpe`` (a folder of CFPE frames ``CCIIh.png``) or ``sphere`` (the dptpu-sphere folder); else ValueError."""
    path = Path(path)
    if not path.is_dir():
        raise FileNotFoundError(f"{path}: no such folder (--measured takes ../shared/data/cfpe or "
                                "../shared/data/dptpu-sphere)")
    if (path / "standardball_phase_real.mat").is_file():
        return "sphere"
    if any(path.glob("??00h.png")):
        return "cfpe"
    raise ValueError(f"{path}: neither a CFPE folder (CCIIh.png frames) nor the dptpu-sphere folder "
                     "(standardball_phase_real.mat)")


def measured_pairs(path, options: DownstreamOptions) -> tuple:
    """``(design, pairs, rig)``: the pair design, the measured pairs, and the real rig for 3D errors (sphere)."""
    kind = measured_kind(path)
    if kind == "cfpe":
        return replace(CFPE_DESIGN, low=options.cfpe_low), _cfpe_pairs(path, options), None
    rig = real_sphere.load_rig(path, "real", relative_pose="all-views")
    levels = twin_levels(rig, real_sphere.load_phase(path, "real"))
    pairs = [sphere_pair(path, noise_sigma=s, seed=options.seed + i, rig=rig, levels=levels)
             for i, s in enumerate(options.noise)]
    return SPHERE_DESIGN, pairs, rig


def _cfpe_pairs(path, options: DownstreamOptions) -> list[MeasuredPair | CascadePair]:
    """The CFPE scenes' pairs (:class:`MeasuredPair`) or cascades (:class:`CascadePair`), as captured and/or with
    the projector's response compensated (calibrated on the other three scenes, named ``cfpeSS/compensated``)."""
    cascade = options.cfpe_low == CASCADE
    pairs: list[MeasuredPair | CascadePair] = []
    for scene in options.cfpe_scenes:
        if "captured" in options.cfpe_responses:
            pairs.append(cfpe_cascade(path, scene) if cascade else cfpe_pair(path, scene, low=options.cfpe_low))
        if "compensated" in options.cfpe_responses:
            others = [s for s in ("01", "04", "06", "08") if s != scene]
            error = cfpe_phase_error(path, others)
            response = (f"compensated: the 3-step phases' error {error.cos_rad:+.4f} cos(3 psi) {error.sin_rad:+.4f} "
                        f"sin(3 psi) rad, fitted on scenes {', '.join(others)}, removed (fpp.phase_harmonics)")
            if cascade:
                levels = cfpe_cascade(path, scene, phase_error=error)
                top = _compensated(levels.top, response)
                pairs.append(replace(levels, top=top, beat=replace(levels.beat, name=f"{top.name}/beat")))
            else:
                pairs.append(_compensated(cfpe_pair(path, scene, low=options.cfpe_low, phase_error=error), response))
    return pairs


def _compensated(pair: MeasuredPair, response: str) -> MeasuredPair:
    """``pair`` named ``NAME/compensated``, its provenance saying how the response was removed."""
    return replace(pair, name=f"{pair.name}/compensated", provenance={**pair.provenance, "response": response})

def split_rigs(extended, base_rig=None, *, measured=None) -> tuple:
    """``(baseline rig, extended rig)`` from a rig file with effects, or an effects file and a base rig.

    Parameters
    ----------
    extended : path or "cfpe-response"
        ``extended_rig.yaml`` (``dptpu-rig/1`` with ``effects``) or ``extended_effects.yaml`` (``effects:`` only,
        from a self-reference diagnosis); or :data:`CFPE_RESPONSE`: the CFPE projector's response calibrated on
        all four scenes of ``measured`` (:func:`dptpu.sim.diagnosis.cfpe_response.cfpe_response_effects`).
    base_rig : str or Rig, optional
        The rig for an effects file (default ``nominal``); with a rig file, its geometry is used and this is
        ignored. For CFPE its camera is widened to see the projector's whole width, as CFPE's camera does
        (:func:`dptpu.sim.diagnosis.cfpe_response.cfpe_twin_rig`).
    measured : path, optional
        The measured data (``--measured``): CFPE for :data:`CFPE_RESPONSE`.
    """
    cfpe = measured is not None and measured_kind(measured) == "cfpe"

    def geometry(source):
        rig = load_twin_rig(source if source is not None else "nominal")
        return cfpe_twin_rig(rig) if cfpe else rig

    if str(extended) == CFPE_RESPONSE:
        if not cfpe:
            raise ValueError(f"--extended {CFPE_RESPONSE} needs --measured a CFPE folder; got {measured}")
        effects, _ = cfpe_response_effects(measured, ("01", "04", "06", "08"))
        rig = geometry(base_rig)
        return replace(rig, effects=()), replace(rig, effects=tuple(effects))
    path = Path(extended)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such extended rig or effects file")
    document = yaml.safe_load(path.read_text()) or {}
    if not isinstance(document, dict) or "effects" not in document:
        raise ValueError(f"{path}: expected a dptpu-rig/1 file with 'effects' or an effects file ('effects: [...]')")
    effects = document["effects"] or []
    parse_effects(effects, source=str(path))  # checked here, with the file's name
    rig = load_twin_rig(path) if document.get("format") == "dptpu-rig/1" else geometry(base_rig)
    return replace(rig, effects=()), replace(rig, effects=tuple(effects))


def solver_orders(models: dict, pair: MeasuredPair | CascadePair, threads: int = 1) -> tuple[dict, dict]:
    """``(orders, voted)``: each solver's order map on ``pair`` (name -> (H, W) int32), and the same after the
    neighbour vote, the same step for every solver.

    ``classical`` is the pair's classical order; each model of ``models`` (name -> ONNX path) is run the way the
    unwrap node runs it (:func:`dptpu.models.refine.refine_order_and_confidence` without its vote: the physics
    prior, the rounded output). A :class:`CascadePair` is solved level by level (:func:`cascade_orders`): each
    solver at level 1, then at level 2 on the low phase of its own level-1 order. ``voted`` is
    :func:`dptpu.models.consensus.consensus_order` of each (top-level) order with the classical order voting beside
    it (for the classical order: the classical order on itself): the vote uses only the wrapped phase and the orders
    (no network), so what it fixes counts for every solver alike. (The unwrap node's own vote takes the network's
    prior instead of the classical order, for MF the order read at the projector's ends,
    :mod:`dptpu.models.projector_ends`; on CFPE, whose camera sees the projector's whole width, that prior is
    right on fewer pixels than the classical order: docs/sim-to-real.md.)
    """
    if isinstance(pair, CascadePair):
        orders = cascade_orders(models, pair, threads)[1]
        return orders, _vote(orders, pair.top)
    orders = {"classical": np.asarray(pair.coarse_order, dtype=np.int32)}
    for name, path in models.items():
        orders[name] = _model_order(FringeOrderModel.load(path, threads=threads), pair)
    return orders, _vote(orders, pair)


def _vote(orders: dict, pair: MeasuredPair) -> dict:
    """Each order of ``orders`` after :func:`dptpu.models.consensus.consensus_order`, ``orders["classical"]``
    voting beside it."""
    psi = np.where(pair.valid, pair.wrapped_high, 0.0)
    return {name: consensus_order(order, orders["classical"], psi, pair.valid) for name, order in orders.items()}


def _model_order(model: FringeOrderModel, pair: MeasuredPair) -> np.ndarray:
    """The network's own order on an MF pair, as the unwrap node runs it without the vote, (H, W) int32."""
    return refine_order_and_confidence(model, pair.method, pair.wrapped_high, pair.wrapped_low, pair.coarse_order,
                                       pair.frequency_high, pair.frequency_low, pair.valid, consensus=False)[0]


def cascade_orders(models: dict, cascade: CascadePair, threads: int = 1, *,
                   vote_beat: bool = False) -> tuple[dict, dict]:
    """``(beat_orders, orders)``: each solver's level-1 order (level 1's convention) and its top-level order.

    ``classical``: Eq. (5) at both levels (the heterodyne). Each model of ``models`` (name -> ONNX path): the
    network on level 1's pair with its classical order as the prior, then on the level-2 pair built from its own
    level-1 order (:meth:`CascadePair.top_pair`) with that pair's classical order as the prior. ``vote_beat``:
    each level-1 order goes through the neighbour vote first (:func:`_vote`, the classical level-1 order beside it)
    and level 2 is built from the voted order (``beat_orders`` are then the voted ones).
    """
    loaded = {name: FringeOrderModel.load(path, threads=threads) for name, path in models.items()}
    beat_orders = _beat_orders(loaded, cascade)
    if vote_beat:
        beat_orders = _vote(beat_orders, cascade.beat)
    return beat_orders, _top_orders(loaded, cascade, beat_orders)


def _beat_orders(models: dict, cascade: CascadePair) -> dict:
    """Level 1: the classical order and each loaded model's (name -> FringeOrderModel)."""
    orders = {"classical": np.asarray(cascade.beat.coarse_order, dtype=np.int32)}
    orders.update({name: _model_order(model, cascade.beat) for name, model in models.items()})
    return orders


def _top_orders(models: dict, cascade: CascadePair, beat_orders: dict) -> dict:
    """Level 2 of each solver from its level-1 order: Eq. (5) for ``classical``, each loaded model otherwise."""
    orders = {"classical": np.asarray(cascade.top_pair(beat_orders["classical"]).coarse_order, dtype=np.int32)}
    orders.update({name: _model_order(model, cascade.top_pair(beat_orders[name])) for name, model in models.items()})
    return orders


def evaluate_orders(pair: MeasuredPair, orders: dict, rig=None, *, voted: dict | None = None) -> dict[str, Any]:
    """Accuracy of each order map of ``orders`` (name -> (H, W)) on ``pair`` (``accuracy``) and of each of
    ``voted`` (``accuracy_vote``, :func:`solver_orders`); 3D errors of ``orders`` when ``rig`` is given."""
    row: dict[str, Any] = {"pair": pair.name, "pixels": int(pair.valid.sum()),
                           "accuracy": {name: order_accuracy(order, pair) for name, order in orders.items()},
                           "provenance": pair.provenance}
    if voted is not None:
        row["accuracy_vote"] = {name: order_accuracy(order, pair) for name, order in voted.items()}
    if rig is not None:
        row["3d"] = {name: sphere_errors_um(pair, order, rig)
                     for name, order in {"reference": pair.reference_order, **orders}.items()}
    return row


def _score(models: dict, pair: MeasuredPair | CascadePair, threads: int, rig=None) -> dict[str, Any]:
    """One row of the results: :func:`evaluate_orders` of :func:`solver_orders`. For a cascade also each solver's
    level-1 order (``accuracy_beat``: the fraction of pixels with the reference beat order) and its top-level order
    with the same vote at each level (``accuracy_vote_levels``: level 1's order voted before level 2 is built from
    it, then the top-level vote), every solver alike."""
    if not isinstance(pair, CascadePair):
        orders, voted = solver_orders(models, pair, threads)
        return evaluate_orders(pair, orders, rig, voted=voted)
    loaded = {name: FringeOrderModel.load(path, threads=threads) for name, path in models.items()}
    beat_orders = _beat_orders(loaded, pair)
    orders = _top_orders(loaded, pair, beat_orders)
    row = evaluate_orders(pair.top, orders, rig, voted=_vote(orders, pair.top))
    row["accuracy_beat"] = {name: order_accuracy(order, pair.beat) for name, order in beat_orders.items()}
    voted_levels = _vote(_top_orders(loaded, pair, _vote(beat_orders, pair.beat)), pair.top)
    row["accuracy_vote_levels"] = {name: order_accuracy(order, pair.top) for name, order in voted_levels.items()}
    return row


def response_check(measured, baseline_rig, extended_rig, size, seed: int = 0) -> dict[str, Any]:
    """The 3-step phase's harmonic error (radians x cos / sin(3 psi)) measured on the real CFPE frames (all four
    scenes) and rendered by each twin (:func:`dptpu.sim.diagnosis.cfpe_response.rendered_phase_error`)."""
    real = cfpe_phase_error(measured, ("01", "04", "06", "08"))
    check: dict[str, Any] = {"measured": {"cos_rad": real.cos_rad, "sin_rad": real.sin_rad}}
    for name, rig in (("baseline_twin", baseline_rig), ("extended_twin", extended_rig)):
        rendered = rendered_phase_error(resize_camera(rig, size), rig.effects, seed=seed)
        check[name] = {"cos_rad": rendered.cos_rad, "sin_rad": rendered.sin_rad}
    return check


def twin_set_pairs(data_dir) -> list[MeasuredPair]:
    """Held-out twin samples as pairs (their label is the reference)."""
    pairs = []
    for path in list_samples(data_dir):
        s = read_sample(path)
        pairs.append(MeasuredPair(
            name=f"{Path(data_dir).name}/{s.name}", wrapped_high=s.wrapped_high.astype(np.float64),
            wrapped_low=s.wrapped_low.astype(np.float64), coarse_order=s.coarse_order.astype(np.int32),
            reference_order=s.label_order.astype(np.int32), reference_phase=np.full(s.valid.shape, np.nan),
            valid=s.valid, frequency_high=s.frequency_high, frequency_low=s.frequency_low, method=s.method,
            extent_px=0, provenance={"data": f"twin, noise {s.noise_sigma:g} DN"}))
    return pairs


def run_downstream(measured, extended, out_dir, *, model, base_rig=None,
                   options: DownstreamOptions = DownstreamOptions(), threads: int = 1, log=None,
                   progress: bool = False) -> dict:
    """The whole downstream comparison (module docstring); writes into ``out_dir`` and returns the report dict.

    Parameters
    ----------
    measured : path
        ``../shared/data/cfpe`` or ``../shared/data/dptpu-sphere``.
    extended : path
        The diagnosis' ``extended_rig.yaml`` or ``extended_effects.yaml`` (:func:`split_rigs`).
    out_dir : path
    model : path
        The base model: an exported ``.onnx`` (weights read back) or a training ``.ckpt``.
    base_rig : str, optional
        Rig for an effects file (default ``nominal``).
    threads : int
        onnxruntime threads of the evaluation (torch's are the caller's).
    log : callable, optional
        Called with a line of progress.
    progress : bool
        tqdm bars on stderr: the twin sets' scenes, each fine-tune's epochs, the scoring.
    """
    log = log or (lambda text: None)
    started = time.perf_counter()
    design, pairs, rig = measured_pairs(measured, options)
    log(f"{len(pairs)} measured pairs ({design.name}), {time.perf_counter() - started:.0f} s")
    baseline_rig, extended_rig = split_rigs(extended, base_rig, measured=measured)
    report = compare_finetunes(pairs, design, baseline_rig, extended_rig, out_dir, model=model, options=options,
                               sphere_rig=rig, threads=threads, log=log, progress=progress)
    if design.name == "cfpe":
        report["response_check"] = response_check(measured, baseline_rig, extended_rig, options.size, options.seed)
    report.update({"measured": str(measured), "extended": str(extended),
                   "seconds": round(time.perf_counter() - started, 1)})
    write_downstream_report(report, out_dir)
    return report


def compare_finetunes(pairs: list, design, baseline_rig, extended_rig, out_dir, *, model,
                      options: DownstreamOptions = DownstreamOptions(), sphere_rig=None, threads: int = 1,
                      log=None, progress: bool = False) -> dict:
    """Steps 2-4 of the module docstring on given measured ``pairs``; returns the report dict (not written).
    ``progress``: tqdm bars on stderr (the twin sets' scenes, each fine-tune's epochs, the scoring).

    ``design`` (:class:`~.twin_pairs.PairDesign`) is how the pairs were built; ``baseline_rig`` and
    ``extended_rig`` differ only by their effects; ``sphere_rig`` (the real rig) adds the sphere's 3D errors.
    """
    log = log or (lambda text: None)
    started = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if options.max_correction != -1:
        design = replace(design, max_correction=options.max_correction)
    sets: dict[str, Path] = {}
    heldout: dict[str, Any] = {}  # name -> a held-out set's folder, or its cascades
    for name, twin in (("baseline", baseline_rig), ("extended", extended_rig)):
        sets[name] = write_twin_set(twin, design, out / f"twin_{name}", scenes=options.scenes, size=options.size,
                                    noise=options.noise, seed=options.seed, progress=progress)
        if options.heldout_scenes > 0 and design.low == CASCADE:
            heldout[name] = twin_cascades(twin, design, scenes=options.heldout_scenes, size=options.size,
                                          noise=options.noise, seed=options.seed + 1000, name=f"heldout_{name}",
                                          progress=progress)
        elif options.heldout_scenes > 0:
            heldout[name] = write_twin_set(twin, replace(design, max_correction=None), out / f"heldout_{name}",
                                           scenes=options.heldout_scenes,
                                           size=options.size, noise=options.noise, seed=options.seed + 1000,
                                           progress=progress)
        log(f"twin set {name}: {options.scenes} scenes, {time.perf_counter() - started:.0f} s")
    start = load_start_model(model)
    base_onnx = Path(model)
    if base_onnx.suffix != ".onnx":  # a checkpoint: export it to score the base model like the others
        from dptpu.models.export import export_onnx  # torch: only to export a checkpoint

        base_onnx = export_onnx(start[0], out / "base.onnx")
    models = {"base": str(base_onnx)}
    runs = {}
    for name in ("baseline", "extended"):
        fresh = (copy.deepcopy(start[0]), *start[1:])  # the same start weights for both
        runs[name] = finetune(fresh, sets[name], out / f"finetuned_{name}.onnx", options.finetune, progress=progress)
        models[f"finetuned_{name}"] = runs[name]["onnx"]
        log(f"fine-tune on the {name} twin: {runs[name]['epochs']} epochs, {runs[name]['seconds']:.0f} s")
    rows = [_score(models, pair, threads, sphere_rig)
            for pair in tqdm(pairs, desc="scoring", unit="pair", disable=not progress, file=sys.stderr)]
    twin_rows = {name: [_score(models, p, threads) for p in (held if design.low == CASCADE else twin_set_pairs(held))]
                 for name, held in heldout.items()}
    return {
        "design": design.as_dict(),
        "effects": {"baseline": [dict(e) for e in baseline_rig.effects],
                    "extended": [dict(e) for e in extended_rig.effects]},
        "base_model": str(model), "start": start[3], "models": models,
        "options": json.loads(json.dumps(asdict(options), default=str)), "finetune_runs": runs,
        "measured_results": rows,
        "twin_results": {name: [{k: r[k] for k in ("pair", "pixels", *_ACCURACIES) if k in r} for r in rs]
                         for name, rs in twin_rows.items()},
        "summary": _summary(rows, twin_rows), "seconds": round(time.perf_counter() - started, 1),
    }


#: The readings of a row (:func:`_score`): own order, after the vote; for a cascade also level 1's order and the
#: vote at each level.
_ACCURACIES = ("accuracy", "accuracy_vote", "accuracy_beat", "accuracy_vote_levels")


def _mean(values) -> float:
    return float(np.mean(values)) if values else float("nan")


def _group(row: dict) -> str:
    """``measured`` or ``compensated`` (a CFPE pair with the projector's response removed)."""
    return "compensated" if row["pair"].endswith("/compensated") else "measured"


def _summary(rows: list, twin_rows: dict) -> dict[str, Any]:
    """Means per group and scoring, and whether each model is above the classical order on every pair."""
    names = ["classical", *MODEL_NAMES]
    summary: dict[str, Any] = {}
    for group in ("measured", "compensated"):
        grouped = [r for r in rows if _group(r) == group]
        if not grouped:
            continue
        for key in _ACCURACIES:
            if key not in grouped[0]:
                continue
            means = {n: _mean([r[key][n] for r in grouped]) for n in names}
            summary[f"{group}_{key}_mean"] = means
            summary[f"{group}_{key}_above_classical_every_pair"] = {
                n: all(r[key][n] > r[key]["classical"] for r in grouped) for n in MODEL_NAMES}
            summary[f"{group}_{key}_gain_of_extension"] = means["finetuned_extended"] - means["finetuned_baseline"]
    for twin, rs in twin_rows.items():
        for key in _ACCURACIES:
            if rs and key in rs[0]:
                summary[f"twin_{twin}_{key}_mean"] = {n: _mean([r[key][n] for r in rs]) for n in names}
    if rows and "3d" in rows[0]:
        summary["interior_sphere_rms_um"] = {r["pair"]: {n: r["3d"][n]["interior_sphere_rms_um"]
                                                         for n in ["reference", *names]} for r in rows}
    return summary


def _accuracy_table(title: str, rows: list, key: str, names: list) -> list[str]:
    lines = ["", title, "", "| pair | pixels | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for row in rows:
        lines.append(f"| {row['pair']} | {row['pixels']} | " + " | ".join(f"{row[key][n]:.4f}" for n in names) + " |")
    return lines


def _markdown(report: dict) -> str:
    names = ["classical", *MODEL_NAMES]
    runs = report["finetune_runs"]
    lines = ["## Downstream gain", "",
             f"Measured data `{report.get('measured', 'given pairs')}`, pair design `{report['design']['name']}` "
             f"(f_h = {report['design']['frequencies'][0]:.4g}, low phase `{report['design']['low']}`); extended twin "
             f"`{report.get('extended', '')}`: effects {report['effects']['extended']}. "
             f"Base model `{report['base_model']}`; both fine-tunes from its weights with the same budget "
             f"({runs['baseline']['steps']} steps: {runs['baseline']['seconds']:.0f} s "
             f"and {runs['extended']['seconds']:.0f} s)."]
    if "response_check" in report:
        check = report["response_check"]
        lines += ["", "The 3-step phase's error at three times the phase (rad x sin(3 psi), against 12 steps): "
                  + ", ".join(f"{name.replace('_', ' ')} {value['sin_rad']:+.4f}" for name, value in check.items())
                  + "."]
    twins = [r for rows in report["twin_results"].values() for r in rows]
    for key, what in (("accuracy", "each solver's own order (the networks without the vote)"),
                      ("accuracy_vote", "each solver's order after the same neighbour vote"),
                      ("accuracy_beat", "each solver's level-1 (beat) order of the cascade"),
                      ("accuracy_vote_levels", "each solver's cascade with the same vote at each level")):
        if key not in report["measured_results"][0]:
            continue
        lines += _accuracy_table(f"Fringe-order accuracy (fraction of valid pixels with the reference order), {what}:",
                                 [*report["measured_results"], *twins], key, names)
    rows3d = [r for r in report["measured_results"] if "3d" in r]
    if rows3d:
        lines += ["", "3D error on the sphere (um; sphere fit with a free radius, interior = 2 px edge band left out; "
                  "point error = RMS distance to the points of the reference order):", "",
                  "| pair | order | interior sphere RMS | all-pixel sphere RMS | point error RMS |",
                  "|---|---|---|---|---|"]
        for row in rows3d:
            for n in ["reference", *names]:
                e = row["3d"][n]
                lines.append(f"| {row['pair']} | {n} | {e['interior_sphere_rms_um']:.1f} | {e['sphere_rms_um']:.1f} | "
                             f"{e['point_error_rms_um']:.1f} |")
    lines += ["", "What is real and what is synthesized:", ""]
    for key, value in report["measured_results"][0]["provenance"].items():
        lines.append(f"- {key}: {value}")
    return "\n".join(lines) + "\n"


def write_downstream_report(report: dict, out_dir) -> None:
    """``downstream.json`` and the "Downstream gain" section of ``report.md`` (appended, or a new file)."""
    out = Path(out_dir)
    (out / "downstream.json").write_text(json.dumps(report, indent=2, default=str))
    path = out / "report.md"
    text = path.read_text() if path.is_file() else "# Twin diagnosis\n\n"
    if "## Downstream gain" in text:
        text = text[:text.index("## Downstream gain")]
    path.write_text(text.rstrip("\n") + "\n\n" + _markdown(report))
