"""The diagnosis: hold measured data against the twin, name what differs, extend the twin, measure the gain.

1. Read the data (:mod:`.measured`): raw frames or a phase file.
2. Register the reference object (:mod:`.registration`), or, with self-reference, take the data's own phase
   (:mod:`.pixels`).
3. Fit every candidate effect with the twin in the loop (:mod:`.candidates`, :mod:`.noise`) and score it
   (:mod:`.selection`): geometric ones on the phase residual, photometric ones on the intensity residual over
   the geometry of the best geometric model, the random part on what the best deterministic model leaves.
4. Rank: named (significant) deterministic effects by gain, then the noise; the cause is the first named one,
   or ``"none"``.
5. Extend: the rig plus the named effects (the cause, and the noise when it is named too), rendered again.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from dptpu.fpp.calibration import Rig

from .candidates import PHOTOMETRIC, fit_lens_distortion, fit_photometric
from .forward import intensity_residual
from .measured import Measured, load_measured
from .noise import fit_sensor_noise
from .pixels import DEFAULT_MAX_PIXELS, reference_pixels, self_reference_pixels
from .reference import Reference, parse_reference
from .registration import register
from .selection import significant

__all__ = ["Diagnosis", "diagnose", "effect_entry"]


@dataclass
class Diagnosis:
    """Everything a report needs: ``cause``, ranked ``effects`` (report.json entries, each with ``named``),
    the arrays behind the figures, and the extended effects."""

    cause: str
    effects: list
    measured: Measured
    rig: Rig
    reference: Reference
    registration: object = None
    geometry: object = None
    pixels: object = None
    pixel_mask: np.ndarray | None = None
    residual_before: list | None = None
    residual_after: list | None = None
    model_before: list | None = None
    extended_effects: list = field(default_factory=list)
    material: object = None

    @property
    def named(self) -> list:
        return [e for e in self.effects if e["named"]]


def effect_entry(entry: dict) -> dict:
    """The twin effect (``{name: {params}}``) of a report entry."""
    return {entry["name"]: dict(entry["parameters"])}


def _reference_material(reference: Reference, rig: Rig):
    from dptpu.sim.scenes import load_scene

    name = "plane" if reference.kind == "plane" else "sphere"
    return load_scene(name, rig).meshes[0].material


def diagnose(measured, rig: Rig, *, reference=None, self_reference: bool = False, frequency=None,
             max_pixels: int = DEFAULT_MAX_PIXELS, seed: int = 0, candidates=PHOTOMETRIC) -> Diagnosis:
    """Diagnose ``measured`` (a path or :class:`Measured`) against the twin of ``rig``.

    Parameters
    ----------
    measured : path-like or Measured
        Capture folder, ``.npz`` or ``.mat`` phase file (:func:`~.measured.load_measured`).
    rig : Rig
        The baseline rig (its effects are ignored: the baseline twin is ideal).
    reference : str or Reference, optional
        ``sphere:DIAMETER_MM`` or ``plane``; required unless ``self_reference``.
    self_reference : bool
        No reference object: the data's own phase is the reference (raw frames needed).
    frequency : float, optional
        Frequency of a ``.mat`` phase file.
    max_pixels : int
        Pixels used by the photometric fits.
    candidates : sequence of Candidate
        Photometric candidates (default all of :data:`~.candidates.PHOTOMETRIC`).
    """
    if not isinstance(measured, Measured):
        measured = load_measured(measured, frequency=frequency, decode=not self_reference)
    rig = None if rig is None else replace(rig, effects=())
    if self_reference:
        if not measured.has_frames:
            raise ValueError(f"{measured.source}: --self-reference needs raw frames (a capture folder)")
        reference = Reference("self")
        pixels, mask = self_reference_pixels(measured, max_pixels=max_pixels, seed=seed)
        entries, registration, geometry, material, refine = [], None, None, None, 2
    else:
        reference = reference if isinstance(reference, Reference) else parse_reference(reference)
        if reference.kind not in ("sphere", "plane"):
            raise ValueError("the diagnosis needs --reference sphere:DIAMETER_MM or plane, or --self-reference; "
                             f"got {reference.label!r}")
        if rig is None:
            raise ValueError("a diagnosis against a reference object needs the rig (--rig)")
        if measured.fringe_axis != "x":
            raise ValueError(f"{measured.source}: the diagnosis reads fringe_axis x captures; got y")
        registration = register(rig, reference, measured.projector_x, measured.valid)
        lens, with_lens = fit_lens_distortion(rig, reference, measured.projector_x, registration)
        lens["named"] = significant(lens)
        entries = [lens]
        geometry = with_lens if lens["named"] else registration
        material = _reference_material(reference, rig)
        pixels = mask = None
        if measured.has_frames:
            pixels, mask = reference_pixels(measured, geometry.rig, reference, geometry.pose, material,
                                             max_pixels=max_pixels, seed=seed)
        refine = 1
    residual_before = residual_after = model_before = None
    best_photometric = None
    if pixels is not None and pixels.size:
        residual_before, _, model_before = intensity_residual(pixels, (), refine=refine)
        rss0 = float(sum(np.sum(r * r) for r in residual_before))
        for candidate in candidates:
            entry = fit_photometric(pixels, candidate, refine=refine, rss_before=rss0)
            entry["named"] = significant(entry)
            entries.append(entry)
        photometric = [e for e in entries if e["evidence"]["domain"] == "intensity" and e["named"]]
        best_photometric = max(photometric, key=lambda e: e["gain"]) if photometric else None
        base = [effect_entry(best_photometric)] if best_photometric else []
        residual_after, _, model_after = intensity_residual(pixels, base, refine=refine)
        noise = fit_sensor_noise(residual_after, model_after)
        noise["named"] = significant(noise)
        entries.append(noise)
    deterministic = sorted([e for e in entries if e["named"] and e["name"] != "sensor_noise"],
                           key=lambda e: -e["gain"])
    noise_named = [e for e in entries if e["named"] and e["name"] == "sensor_noise"]
    rest = sorted([e for e in entries if not e["named"]], key=lambda e: -e["evidence"]["delta_bic"])
    ranked = deterministic + noise_named + rest
    cause = ranked[0]["name"] if ranked and ranked[0]["named"] else "none"
    extended = [effect_entry(deterministic[0])] if deterministic else []
    extended += [effect_entry(e) for e in noise_named]
    return Diagnosis(cause=cause, effects=ranked, measured=measured, rig=rig, reference=reference,
                     registration=registration, geometry=geometry, pixels=pixels, pixel_mask=mask,
                     residual_before=residual_before, residual_after=residual_after, model_before=model_before,
                     extended_effects=extended, material=material)
