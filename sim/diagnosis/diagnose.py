"""The diagnosis: hold measured data against the twin, name what differs, extend the twin, measure the gain.

1. Read the data (:mod:`.measured`): raw frames or a phase file.
2. Register the reference object (:mod:`.registration`; a scene file: :mod:`.scene_registration`), or, with
   self-reference, take the data's own phase (:mod:`.pixels`).
3. Fit every candidate effect with the twin in the loop (:mod:`.candidates`, :mod:`.motion`, :mod:`.response`,
   :mod:`.noise`) and score it (:mod:`.selection`): geometric ones on the phase residual, photometric ones on
   the intensity residual over the geometry of the best geometric model, the random part on what the best
   deterministic model leaves. A candidate the data cannot show is reported with the reason
   (:data:`~.candidates.NOT_IDENTIFIABLE`).
4. Rank: named (significant) deterministic effects by gain, then the noise; the cause is the first named one,
   or ``"none"``. With ``rounds > 1`` further photometric effects are added greedily on top of the cause.
5. Extend: the rig plus the named effects (the cause, and the noise when it is named too), rendered again.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.sim.scenes import load_scene

from .blur_correction import BLUR_EFFECTS, blur_bias
from .calibration_fit import NOT_IDENTIFIABLE_ON_SCENE, fit_calibration_error
from .candidates import (
    NOT_IDENTIFIABLE,
    PHOTOMETRIC,
    fit_geometric_extra,
    fit_lens_distortion,
    fit_photometric,
    not_identifiable,
)
from .correlated_noise import fit_phase_filter_on_phase_file
from .footprint_fit import edge_defocus_entry, fit_pixel_footprint
from .forward import PixelSet, intensity_residual
from .measured import Measured, load_measured
from .motion import fit_motion, identifiable_directions
from .noise import fit_sensor_noise
from .phase_candidates import PHASE_VISIBLE, fit_phase_candidate
from .pixels import DEFAULT_MAX_PIXELS, erode_mask, reference_pixels, self_reference_pixels
from .recentred_orders import recentred_absolute_phase
from .reference import Reference, load_scene_reference, parse_reference
from .registration import Registration, register, register_robust
from .response import fit_response
from .scene_registration import fit_scene_lens_distortion, register_scene
from .selection import MIN_DELTA_BIC, delta_bic, gain, significant

__all__ = ["Diagnosis", "diagnose", "effect_entry", "EDGE_BAND_PX"]

#: Noise is named only when its excess variance exceeds this many times the variance the best deterministic
#: candidate explains.
NOISE_OVER_SYSTEMATIC = 4.0
#: Pixels next to the border of the measured region left out of the geometric fits (mixed pixels).
EDGE_BAND_PX = 2
#: Rounds of the geometric candidates under the named blurs (:mod:`.blur_correction`), each with the blurs fitted
#: again against the geometry it finds; they end early when the blurs stay within ``BLUR_TOLERANCE``.
BLUR_ROUNDS = 3
BLUR_TOLERANCE = 0.03
#: The pose the blurs are first fitted against is registered on the pixels this far inside the measured region.
BLUR_POSE_MARGIN_PX = 6
#: Fewer pixels that deep (a small region): the blurs are fitted against the registration itself.
MIN_DEEP_PIXELS = 100


@dataclass
class Diagnosis:
    """Everything a report needs: ``cause``, ranked ``effects`` (report.json entries, each with ``named``),
    the arrays behind the figures, and the extended effects."""

    cause: str
    effects: list
    measured: Measured
    rig: Rig | None
    reference: Reference
    registration: Registration | None = None
    geometry: Registration | None = None
    pixels: PixelSet | None = None
    pixel_mask: np.ndarray | None = None
    residual_before: list | None = None
    residual_after: list | None = None
    model_before: list | None = None
    extended_effects: list = field(default_factory=list)
    material: object = None
    additional: list = field(default_factory=list)
    corrected_rig: Rig | None = None

    @property
    def named(self) -> list:
        return [e for e in self.effects if e["named"]]


def effect_entry(entry: dict) -> dict:
    """The twin effect (``{name: {params}}``) of a report entry."""
    return {entry["name"]: dict(entry["parameters"])}


def rescore_in_intensity(entry: dict, rss_before: float, rss_after: float, values: int) -> None:
    """Re-score a phase-domain entry on the intensity residual (same pixels, same values), keeping the phase
    figures in its evidence: with raw frames every candidate is then judged on one residual."""
    evidence = entry["evidence"]
    evidence.update({"phase_residual_before_px": entry["residual_before"],
                     "phase_residual_after_px": entry["residual_after"], "phase_delta_bic": evidence["delta_bic"],
                     "domain": "intensity", "unit": "DN", "values": values,
                     "delta_bic": delta_bic(rss_before, rss_after, values, evidence["parameters"])})
    before, after = float(np.sqrt(rss_before / values)), float(np.sqrt(rss_after / values))
    entry.update({"residual_before": before, "residual_after": after, "gain": gain(before, after)})


#: Two models of one thing, the projector's response: never both in the extended twin.
RESPONSE_ALTERNATIVES = ("projector_gamma", "projector_response")


def _response_entry(pixels, entries, *, refine: int, rss_before: float) -> dict:
    """The lookup-table response, named only when the BIC prefers it to every one-parameter photometric
    candidate by more than ``MIN_DELTA_BIC`` (its many knots must buy more than the best single parameter); when
    it is named, the power law it replaces is not."""
    entry = fit_response(pixels, refine=refine, rss_before=rss_before)
    single = [e for e in entries if e["evidence"]["domain"] == "intensity" and e["evidence"]["parameters"] == 1]
    best = max(single, key=lambda e: e["evidence"]["delta_bic"], default=None)
    margin = entry["evidence"]["delta_bic"] - (best["evidence"]["delta_bic"] if best else 0.0)
    entry["evidence"]["delta_bic_over_best_single"] = margin
    entry["named"] = significant(entry) and margin > MIN_DELTA_BIC
    if entry["named"]:
        for e in entries:
            if e["name"] == "projector_gamma" and e["named"]:
                e["named"] = False
                e["evidence"]["superseded_by"] = "projector_response"
    return entry


def _recentre_orders(measured: Measured, rig: Rig, reference: Reference, fit_mask, registration):
    """When the data's phases share a bias that eats the MF rounding margin (the centre of the MF rounding over a
    quarter turn, :mod:`.recentred_orders`), or the registration cannot explain the decoded coordinate (orders
    off the twin's, an RMS over a tenth of a period), decode the orders again about that centre, shifted by
    -1, 0 and +1 order everywhere (the centre fixes the orders up to one common order), and keep the decoding
    that registers best."""
    period_px = measured.extent / measured.frequency
    recentred = recentred_absolute_phase(measured, np.isfinite(measured.absolute_phase))
    if recentred is None:
        return registration
    phase, centre = recentred
    broken = registration.order_errors > 0.0 or registration.rms_px > 0.1 * period_px
    if not broken and abs(centre) <= 0.25 * np.pi:
        return registration
    best, best_phase = registration, measured.absolute_phase
    for shift in (0, 1, -1):
        measured.absolute_phase = phase + 2.0 * np.pi * shift
        again = register_robust(rig, reference, measured.projector_x, fit_mask, period_px=period_px)
        if again.rms_px < best.rms_px:
            best, best_phase = again, measured.absolute_phase
    measured.absolute_phase = best_phase
    return best


#: Random effects: ranked after the deterministic ones; an entry's ``extension`` (when present) is what joins the
#: extended twin (``phase_filter``: the read noise it filters, and the filter).
NOISE_LIKE = ("sensor_noise", "phase_filter")
#: Geometric models of one thing, the rig's geometry: one of them in the extended twin.
GEOMETRIC = ("lens_distortion", "calibration_error")


def _best_geometry(registration: Registration, fits) -> Registration:
    """The registration of the named geometric effect that explains most (``fits``: (entry, registration)
    pairs), or ``registration``."""
    named = [(entry["gain"], fitted) for entry, fitted in fits if entry["named"] and fitted is not None]
    return max(named, key=lambda g: g[0])[1] if named else registration


def _quiet(_: str) -> None:
    """No progress report."""


def _blur_entries(measured, geometry, reference, material, step):
    """The blurs fitted against ``geometry``: ``phase_filter`` (a phase file's correlated noise; None with
    frames), ``pixel_footprint`` on the edge band (a sphere) and, on a phase file, its ``camera_defocus``
    alternative as an entry of its own (None otherwise); each with ``named``. When the edge band names a blur,
    the filter is fitted again on the residual less that blur's bias (:mod:`.blur_correction`): a blur's smooth
    pattern reaches into the interior and correlates neighbours like a filter."""
    noise = edge_defocus = None
    filter_sigma = None
    if not measured.has_frames:  # correlated phase noise: on what the best geometric model leaves
        step("phase_filter")
        noise = fit_phase_filter_on_phase_file(measured, geometry, reference, material)
        noise["named"] = significant(noise)
        filter_sigma = noise["parameters"]["sigma_px"] if noise["named"] else None
    if reference.kind != "sphere":
        footprint = not_identifiable("pixel_footprint", "the edge band is fitted on a sphere's silhouette (a "
                                                        "plane's border is the image's or a shadow's, a scene's "
                                                        "is traced)")
        return noise, footprint, None
    step("pixel_footprint")  # the edge band, against the geometric model
    footprint = fit_pixel_footprint(measured, geometry, reference, material, edge_px=EDGE_BAND_PX,
                                    phase_filter_sigma=filter_sigma)
    footprint["named"] = significant(footprint) and footprint["evidence"].get("beats_alternatives", False)
    if not measured.has_frames:  # a phase file: the lens blur after the sampling, seen on the edge band
        edge_defocus = edge_defocus_entry(footprint)
        if edge_defocus is not None:
            edge_defocus["named"] = significant(edge_defocus) and edge_defocus["evidence"]["beats_alternatives"]
        edge = [effect_entry(e) for e in (footprint, edge_defocus) if e is not None and e["named"]]
        if edge and noise is not None:
            step("phase_filter less the edge blur")
            bias = blur_bias(measured, geometry, reference, material, edge)
            noise = fit_phase_filter_on_phase_file(measured, geometry, reference, material, bias=bias)
            noise["named"] = significant(noise)
    return noise, footprint, edge_defocus


def _blur_widths(effects: list) -> dict:
    """``{name: width px}`` of blur effects (``sigma_px``, or the footprint's ``blur_sigma_px``)."""
    return {name: float(p.get("sigma_px", p.get("blur_sigma_px", 0.0))) for e in effects for name, p in e.items()}


def _same_blurs(a: list, b: list, tolerance: float = BLUR_TOLERANCE) -> bool:
    """Whether two lists of blur effects name the same effects with main parameters within ``tolerance``."""
    wa, wb = _blur_widths(a), _blur_widths(b)
    return wa.keys() == wb.keys() and all(abs(wa[k] - wb[k]) <= tolerance * max(abs(wb[k]), 1e-9) for k in wa)

def _reference_material(reference: Reference, rig: Rig):
    if reference.kind == "scene":
        return None  # a traced scene carries its own materials
    name = "plane" if reference.kind == "plane" else "sphere"
    return load_scene(name, rig).meshes[0].material


def diagnose(measured, rig: Rig | None, *, reference=None, self_reference: bool = False, frequency=None,
             max_pixels: int = DEFAULT_MAX_PIXELS, seed: int = 0, candidates=PHOTOMETRIC,
             outside_vocabulary: bool = False, rounds: int = 1, phase_candidates: bool = True,
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Diagnose ``measured`` (a path or :class:`Measured`) against the twin of ``rig``.

    Parameters
    ----------
    measured : path-like or Measured
        Capture folder, ``.npz`` or ``.mat`` phase file (:func:`~.measured.load_measured`).
    rig : Rig or None
        The baseline rig (its effects are ignored: the baseline twin is ideal); None only with
        ``self_reference``.
    reference : str or Reference, optional
        ``sphere:DIAMETER_MM``, ``plane`` or ``scene:FILE``; required unless ``self_reference``.
    self_reference : bool
        No reference object: the data's own phase is the reference (raw frames needed).
    frequency : float, optional
        Frequency of a ``.mat`` phase file.
    max_pixels : int
        Pixels used by the photometric fits.
    candidates : sequence of Candidate
        Photometric candidates (default all of :data:`~.candidates.PHOTOMETRIC`).
    outside_vocabulary : bool
        Also fit the phase-domain explanations the twin has no effect for
        (:func:`~.candidates.fit_geometric_extra`); reported, never named.
    phase_candidates : bool
        With a phase file, fit the photometric effects a 12-step phase shows (:mod:`.phase_candidates`).
    rounds : int
        Photometric effects found greedily: after the cause, each further round fits the remaining candidates
        on top of the effects found so far and adds the best significant one (``Diagnosis.additional``).
    progress : callable, optional
        Called with the name of each step as it starts (``dptpu twin diagnose`` shows them in a progress bar).
    """
    step = progress if progress is not None else _quiet
    if not isinstance(measured, Measured):
        step("reading the data")
        measured = load_measured(measured, frequency=frequency, decode=not self_reference)
    rig = None if rig is None else replace(rig, effects=())
    # the calibration error needs a reference object (a self-reference diagnosis does not report it)
    calibration = not_identifiable("calibration_error", "self-reference: no reference object")
    with_calibration: Registration | None = None
    calibration_pixels = None
    geometry_base: Registration | None = None  # the pose the geometric candidates start from
    if self_reference:
        if not measured.has_frames:
            raise ValueError(f"{measured.source}: --self-reference needs raw frames (a capture folder)")
        reference = Reference("self")
        pixels, mask = self_reference_pixels(measured, max_pixels=max_pixels, seed=seed)
        entries, registration, material, refine, lens_pixels = [], None, None, 2, None
        entries += [not_identifiable(c.name, NOT_IDENTIFIABLE["self"][c.name]) for c in candidates if c.needs]
        entries.append(not_identifiable("motion", NOT_IDENTIFIABLE["self"]["motion"]))
        candidates = [c for c in candidates if not c.needs]
    else:
        reference = reference if isinstance(reference, Reference) else parse_reference(reference)
        if reference.kind not in ("sphere", "plane", "scene"):
            raise ValueError("the diagnosis needs --reference sphere:DIAMETER_MM, plane or scene:FILE, or "
                             f"--self-reference; got {reference.label!r}")
        if rig is None:
            raise ValueError("a diagnosis against a reference object needs the rig (--rig)")
        if measured.fringe_axis != "x":
            raise ValueError(f"{measured.source}: the diagnosis reads fringe_axis x captures; got y")
        reference = load_scene_reference(reference, rig)
        # the silhouette's mixed pixels are the edge band of the decomposition, not evidence for an effect
        fit_mask = erode_mask(measured.valid, EDGE_BAND_PX)
        step("registering the reference")
        if reference.kind == "scene":
            registration = register_scene(rig, reference, measured.projector_x, fit_mask,
                                          period_px=measured.extent / measured.frequency)
        else:
            registration = register_robust(rig, reference, measured.projector_x, fit_mask,
                                           period_px=measured.extent / measured.frequency)
            registration = _recentre_orders(measured, rig, reference, fit_mask, registration)
        if registration.order_errors:  # unwrap the measured phase with the twin's orders instead
            period = 2.0 * np.pi
            model = registration.model_x * 2.0 * np.pi * measured.frequency / measured.extent
            phase = measured.absolute_phase
            measured.absolute_phase = phase + period * np.round((model - phase) / period)
        step("lens_distortion")
        if reference.kind == "scene":
            lens, with_lens = fit_scene_lens_distortion(rig, reference, measured.projector_x, registration)
        else:
            lens, with_lens = fit_lens_distortion(rig, reference, measured.projector_x, registration)
        lens["named"] = significant(lens)
        entries = [lens]
        geometry_base = registration
        if reference.kind == "scene":
            calibration = not_identifiable("calibration_error", NOT_IDENTIFIABLE_ON_SCENE)
            with_calibration = registration
        else:
            step("calibration_error")
            calibration, with_calibration = fit_calibration_error(rig, reference, measured.projector_x,
                                                                  registration)
            calibration["named"] = significant(calibration)
        entries.append(calibration)
        if outside_vocabulary and reference.kind != "scene":
            for extra in fit_geometric_extra(rig, reference, measured.projector_x, registration):
                extra["named"] = False
                entries.append(extra)
        material = _reference_material(reference, rig)
        # the blurs first against the pose alone: a geometric model fitted beside an unmodelled blur absorbs part
        # of it, and a blur fitted against that geometry comes out too narrow
        blur_geometry = registration
        deep = registration.mask & erode_mask(measured.valid, BLUR_POSE_MARGIN_PX)
        if reference.kind != "scene" and deep.sum() >= MIN_DEEP_PIXELS:  # the pose from pixels beyond a blur's reach
            blur_geometry = register(rig, reference, measured.projector_x, deep, pose0=registration.pose)
        noise, footprint, edge_defocus = _blur_entries(measured, blur_geometry, reference, material, step)
        previous: list = []
        first = (lens, with_lens, calibration, with_calibration)
        # a geometric effect named beside a blur is judged again under it: the geometric candidates on the measured
        # less the named blurs' bias (none named: nothing the blurs could have lent them)
        rounds_left = BLUR_ROUNDS if lens["named"] or calibration["named"] else 0
        for _ in range(rounds_left):
            blurs = [effect_entry(e) for e in (footprint, edge_defocus, noise)
                     if e is not None and e["named"] and e["name"] in BLUR_EFFECTS]
            if not blurs or _same_blurs(blurs, previous):
                break
            step("lens_distortion and calibration_error under " + ", ".join(
                f"{name} {width:.3g} px" for name, width in _blur_widths(blurs).items()))
            corrected_x = measured.projector_x - blur_bias(measured, blur_geometry, reference, material, blurs)
            geometry_base = register(rig, reference, corrected_x, blur_geometry.mask, pose0=registration.pose)
            lens, with_lens = fit_lens_distortion(rig, reference, corrected_x, geometry_base)
            calibration, with_calibration = fit_calibration_error(rig, reference, corrected_x, geometry_base)
            for entry in (lens, calibration):
                entry["evidence"]["under_blur"] = {"effects": blurs}
                entry["named"] = significant(entry)
            entries = [lens, calibration] + entries[2:]
            # the blurs again against the pose alone: a geometric effect fitted beside a blur a little off absorbs
            # the rest of it, and a blur fitted against that geometry stays off (the two settle on a biased pair)
            noise, footprint, edge_defocus = _blur_entries(measured, geometry_base, reference, material, step)
            blur_geometry, previous = geometry_base, blurs
        if previous and (lens["named"] or calibration["named"]):
            # a geometric effect holds under the blurs, so it is no blur's: its fit on the data as measured stands
            # (the correction is the twin's at a geometry still without it), and the blurs are read against it
            for before, under in ((first[0], lens), (first[2], calibration)):
                before["evidence"]["under_blur"] = {"effects": previous, "named": under["named"],
                                                    "gain": under["gain"], "parameters": under["parameters"]}
            lens, with_lens, calibration, with_calibration = first
            entries = [lens, calibration] + entries[2:]
            geometry_base = registration
            best_geometry = _best_geometry(registration, ((lens, with_lens), (calibration, with_calibration)))
            noise, footprint, edge_defocus = _blur_entries(measured, best_geometry, reference, material, step)
        entries.append(footprint)
        pixels = mask = lens_pixels = None
        if measured.has_frames:
            pixels, mask = reference_pixels(measured, registration.rig, reference, registration.pose, material,
                                             max_pixels=max_pixels, seed=seed)
            lens_pixels, _ = reference_pixels(measured, with_lens.rig, reference, with_lens.pose, material,
                                              index=pixels.index, motion=False)
            if calibration["evidence"]["parameters"]:
                calibration_pixels, _ = reference_pixels(measured, with_calibration.rig, reference,
                                                         with_calibration.pose, material, index=pixels.index,
                                                         motion=False)
        else:  # a phase file: the photometric effects a 12-step phase shows, judged on the phase

            for candidate in PHASE_VISIBLE if phase_candidates else ():
                step(candidate.name)
                entry = fit_phase_candidate(measured, rig, reference, material, registration, candidate)
                entry["named"] = significant(entry)
                entries.append(entry)
            entries += [edge_defocus if c.name == "camera_defocus" and edge_defocus is not None
                        else not_identifiable(c.name, NOT_IDENTIFIABLE["phase"][c.name]) for c in candidates if c.needs]
            entries.append(not_identifiable("motion", NOT_IDENTIFIABLE["phase"]["motion"]))
            entries.append(noise)
        refine = 1
    residual_before = residual_after = model_before = None
    additional = []
    if pixels is not None and pixels.size:
        residual_before, _, model_before = intensity_residual(pixels, (), refine=refine)
        rss0 = float(sum(np.sum(r * r) for r in residual_before))
        if lens_pixels is not None:  # with frames, the geometric candidate is judged on the frames too
            lens_residual, _, lens_model = intensity_residual(lens_pixels, (), refine=refine)
            rescore_in_intensity(lens, rss0, float(sum(np.sum(r * r) for r in lens_residual)), pixels.values)
            lens["named"] = significant(lens)
        if calibration_pixels is not None:  # the same for the calibration error
            calibration_residual, _, calibration_model = intensity_residual(calibration_pixels, (), refine=refine)
            rescore_in_intensity(calibration, rss0, float(sum(np.sum(r * r) for r in calibration_residual)),
                                 pixels.values)
            calibration["named"] = significant(calibration)
        for candidate in candidates:
            step(candidate.name)
            entry = fit_photometric(pixels, candidate, refine=refine, rss_before=rss0)
            entry["named"] = significant(entry)
            entries.append(entry)
        if registration is not None:
            step("motion")
            motion = fit_motion(pixels, identifiable_directions(rig, reference, registration.pose), refine=refine,
                                rss_before=rss0)
            motion["named"] = significant(motion)
            entries.append(motion)
        step("projector_response")
        entries.append(_response_entry(pixels, entries, refine=refine, rss_before=rss0))
        deterministic = [e for e in entries if e["named"]]
        best = max(deterministic, key=lambda e: e["gain"]) if deterministic else None
        if best is not None and best["name"] == "lens_distortion":
            residual_after, model_after = lens_residual, lens_model
        elif best is not None and best["name"] == "calibration_error":
            residual_after, model_after = calibration_residual, calibration_model
        else:
            base = [effect_entry(best)] if best is not None else []
            for _ in range(max(int(rounds), 1) - 1):  # greedy: what else, on top of the effects found so far
                if not base:
                    break
                on_top = ", ".join(next(iter(b)) for b in base)
                step(f"round {len(base) + 1}: effects on top of {on_top}")
                chosen = {next(iter(b)) for b in base}
                if chosen & set(RESPONSE_ALTERNATIVES):  # one projector response model at a time
                    chosen |= set(RESPONSE_ALTERNATIVES)
                residual, _, _ = intensity_residual(pixels, base, refine=refine)
                rss = float(sum(np.sum(r * r) for r in residual))
                more: list[dict] = []
                for candidate in [c for c in candidates if c.name not in chosen]:  # a step each: seconds per fit
                    step(f"round {len(base) + 1}: {candidate.name} on top of {on_top}")
                    more.append(fit_photometric(pixels, candidate, base=base, refine=refine, rss_before=rss))
                more = [dict(e, evidence=dict(e["evidence"], round=len(base) + 1)) for e in more if significant(e)]
                if not more:
                    break
                top = max(more, key=lambda e: e["gain"])
                top["named"] = True
                additional.append(top)
                base.append(effect_entry(top))
            residual_after, _, model_after = intensity_residual(pixels, base, refine=refine)
        step("sensor_noise")
        noise = fit_sensor_noise(residual_after, model_after)
        # noise is named only when the excess variance is random: far more than any deterministic candidate
        # can explain (a small systematic misfit also raises the residual above quantization)
        systematic = max([e["residual_before"] ** 2 - e["residual_after"] ** 2 for e in entries
                          if e["evidence"]["domain"] == "intensity"] + [0.0])
        noise["evidence"]["systematic_variance_dn2"] = systematic
        noise["named"] = significant(noise) and (
            noise["evidence"]["excess_variance_dn2"] > NOISE_OVER_SYSTEMATIC * systematic)
        entries.append(noise)
    geometry = None
    if geometry_base is not None:  # the geometric effect that explains most, or the registration
        geometry = _best_geometry(geometry_base, ((lens, with_lens), (calibration, with_calibration)))
    deterministic = sorted([e for e in entries if e["named"] and e["name"] not in NOISE_LIKE],
                           key=lambda e: -e["gain"])
    noise_named = [e for e in entries if e["named"] and e["name"] in NOISE_LIKE]
    rest = sorted([e for e in entries if not e["named"]], key=lambda e: -e["evidence"]["delta_bic"])
    ranked = deterministic + noise_named + rest
    cause = ranked[0]["name"] if ranked and ranked[0]["named"] else "none"
    corrected_rig = with_calibration.rig if with_calibration is not None and calibration["named"] else None
    extended = [effect_entry(deterministic[0])] if deterministic else []
    if not measured.has_frames and deterministic:  # a phase file: every named effect joins, one geometric model
        first_geometric = deterministic[0]["name"] in GEOMETRIC
        extended += [effect_entry(e) for e in deterministic[1:] if not (first_geometric and e["name"] in GEOMETRIC)]
    extended += [effect_entry(e) for e in additional]
    extended += [effect for e in noise_named for effect in e.get("extension", [effect_entry(e)])]
    return Diagnosis(cause=cause, effects=ranked, measured=measured, rig=rig, reference=reference,
                     registration=registration, geometry=geometry, pixels=pixels, pixel_mask=mask,
                     residual_before=residual_before, residual_after=residual_after, model_before=model_before,
                     extended_effects=extended, material=material, additional=additional,
                     corrected_rig=corrected_rig)
