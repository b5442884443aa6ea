"""Write a diagnosis: figures, the extended rig, the re-render and its gain, ``report.json`` and ``report.md``.

``report.json`` (keys fixed by the issue)::

    {"cause": NAME or "none",
     "effects": [{"name", "parameters", "residual_before", "residual_after", "gain", "evidence"}, ...],  # ranked
     "extended_rig": PATH,
     "sphere_rms_um": {"measured", "twin", "extended_twin"},     # sphere reference only
     ...}                                                         # plus registration, decomposition, rerender

``evidence`` holds the residual's domain and unit, the number of values, ``delta_bic`` and ``named`` (the
effect passes :func:`dptpu.sim.diagnosis.selection.significant`).
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dptpu.fpp.calibration import save_rig
from dptpu.sim.effects import parse_effects
from dptpu.sim.effects.geometry import render_rig
from dptpu.sim.image_formation import SequenceSpec

from .figures import map_figure, profile_figure
from .forward import fit_gain
from .rerender import decode, render_twin, sphere_rms_um
from .residuals import decompose_intensity, decompose_phase

__all__ = ["write_report", "json_ready", "RERENDER_SEED"]

#: Seed of the re-render's random effects: never the data's own realization, so a re-rendered noise is a new
#: draw (its residual RMS then grows by ~sqrt(2) x the noise; the noise entry's variance match is its gain).
RERENDER_SEED = 20261123
#: Effects that act through the rig the twin renders with (:func:`dptpu.sim.effects.geometry.render_rig`).
RIG_EFFECTS = ("lens_distortion", "calibration_error")


def json_ready(value):
    """Numpy scalars and arrays as plain JSON types, floats rounded to 6 significant digits."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return None if not np.isfinite(value) else float(f"{value:.6g}")
    return value


def _entries(diagnosis) -> list:
    out = []
    for e in diagnosis.effects:
        evidence = dict(e["evidence"], named=bool(e["named"]))
        out.append({"name": e["name"], "parameters": e["parameters"], "residual_before": e["residual_before"],
                    "residual_after": e["residual_after"], "gain": e["gain"], "evidence": evidence})
    return out


def _image(shape, index, values) -> np.ndarray:
    image = np.full(shape, np.nan)
    image[index] = values
    return image


def _intensity_rms(measured_frames, twin_frames, mask) -> float:
    measured = [f[:, mask] for f in measured_frames]
    model = [f[:, mask] for f in twin_frames]
    gain = fit_gain(measured, model)
    residual = np.concatenate([(m - gain * p).ravel() for m, p in zip(measured, model)])
    return float(np.sqrt(np.mean(residual ** 2)))


def _without_random(rig, reference, pose, diagnosis, sequences, effects) -> np.ndarray:
    """Absolute phase of the extended twin without its random effects (sensor noise)."""
    steady = [e for e in effects if e.name not in RIG_EFFECTS and e.stage != "phase" and e.name != "sensor_noise"]
    frames = render_twin(rig, reference, pose, diagnosis.material, sequences, effects=steady)
    return decode(frames, sequences)


def _orders_of(x: np.ndarray, x_steady: np.ndarray, period_px: float) -> np.ndarray:
    """``x`` (projector px) moved by whole periods to the nearest of ``x_steady``."""
    return x + period_px * np.round((x_steady - x) / period_px)


def _rerender(diagnosis, extended_effects) -> dict[str, Any]:
    """Twin and extended twin rendered again: intensity RMS (frames) and phase RMS against the measurement,
    and the sphere-fit RMS of measurement, twin and extended twin."""
    measured, reference, geometry = diagnosis.measured, diagnosis.reference, diagnosis.registration
    if geometry is None:
        return {}
    rig = diagnosis.rig
    effects = parse_effects(extended_effects)
    extended_rig = render_rig(rig, effects)
    extended_pose = diagnosis.geometry.pose
    out: dict[str, Any] = {}
    mask = diagnosis.pixel_mask if diagnosis.pixel_mask is not None else (geometry.mask & np.isfinite(geometry.model_x))
    axis = measured.fringe_axis
    if measured.has_frames:
        kwargs = dict(bit_depth=measured.bit_depth, pattern=measured.pattern, seed=RERENDER_SEED)
        twin = render_twin(rig, reference, geometry.pose, diagnosis.material, measured.sequences, **kwargs)
        reference_frame = diagnosis.pixels.motion_reference_frame if diagnosis.pixels is not None else 0.0
        extended = render_twin(extended_rig, reference, extended_pose, diagnosis.material, measured.sequences,
                               effects=[e for e in effects if e.name not in RIG_EFFECTS],
                               reference_frame=reference_frame, **kwargs)
        out["intensity_rms_dn"] = {"twin": _intensity_rms(measured.frames, twin, mask),
                                   "extended_twin": _intensity_rms(measured.frames, extended, mask)}
        # how far measurement and extended twin each depart from the ideal twin (for noise: equal levels)
        out["departure_from_twin_dn"] = {"measured": out["intensity_rms_dn"]["twin"],
                                         "extended_twin": _intensity_rms(extended, twin, mask)}
        x_twin = decode(twin, measured.sequences, bit_depth=measured.bit_depth) * measured.extent / (
            2 * np.pi * measured.frequency)
        x_extended = decode(extended, measured.sequences, bit_depth=measured.bit_depth,
                            effects=effects) * measured.extent / (
            2 * np.pi * measured.frequency)
    else:  # a phase file: render the paper's sequences (f x 12 and 1 x 12, 8 bit) and decode them the same way

        sequences = [SequenceSpec(measured.frequency, 12), SequenceSpec(1.0, 12)]
        twin = render_twin(rig, reference, geometry.pose, diagnosis.material, sequences)
        extended = render_twin(extended_rig, reference, extended_pose, diagnosis.material, sequences,
                               effects=[e for e in effects if e.name not in RIG_EFFECTS], seed=RERENDER_SEED)
        to_x = measured.extent / (2 * np.pi * measured.frequency)
        x_twin, x_extended = decode(twin, sequences) * to_x, decode(extended, sequences, effects=effects) * to_x
        if diagnosis.registration.order_errors == 0.0:
            # the data's orders are right, so the extended twin's are too: its random effects (noise at the
            # level of the high frequency's phase) act on the phase, not on the orders of our MF decoder
            x_extended = _orders_of(x_extended, _without_random(extended_rig, reference, extended_pose, diagnosis,
                                                                sequences, effects) * to_x,
                                    measured.extent / measured.frequency)
        out["rendered_sequences"] = [s.label for s in sequences]
    x_measured = measured.projector_x
    both = mask & np.isfinite(x_measured) & np.isfinite(x_twin) & np.isfinite(x_extended)
    if both.any():
        out["phase_rms_px"] = {"twin": float(np.sqrt(np.mean((x_measured - x_twin)[both] ** 2))),
                               "extended_twin": float(np.sqrt(np.mean((x_measured - x_extended)[both] ** 2)))}
    if reference.kind == "sphere":
        rms = {}
        for label, x in (("measured", x_measured), ("twin", x_twin), ("extended_twin", x_extended)):
            value, radius = sphere_rms_um(rig, x, both, axis=axis, mm_per_unit=1e-3 / rig.scale_to_m)
            rms[label] = value
            out.setdefault("sphere_radius", {})[label] = radius
        out["sphere_rms_um"] = rms
        out["sphere_pixels"] = int(both.sum())
        # the whole sphere, edge band included: every measured pixel the twin decodes too
        whole = measured.valid & np.isfinite(x_twin) & np.isfinite(x_extended)
        out["sphere_rms_um_whole"] = {
            label: sphere_rms_um(rig, x, whole, axis=axis, mm_per_unit=1e-3 / rig.scale_to_m)[0]
            for label, x in (("measured", x_measured), ("twin", x_twin), ("extended_twin", x_extended))}
        out["sphere_pixels_whole"] = int(whole.sum())
    return out


def _corrected_sphere(diagnosis) -> dict:
    """The measured sphere reconstructed with the given and with the corrected rig: sphere-fit RMS (um) and
    radius (rig units), on the interior (edge band left out) and on every valid pixel."""
    measured, rig = diagnosis.measured, diagnosis.rig
    interior = diagnosis.registration.mask & np.isfinite(measured.projector_x)
    out: dict[str, Any] = {"certified_radius": diagnosis.reference.sphere_diameter / 2.0}
    for region, mask in (("interior", interior), ("whole", measured.valid)):
        for label, calibration in (("given", rig), ("corrected", diagnosis.corrected_rig)):
            rms, radius = sphere_rms_um(calibration, measured.projector_x, mask, axis=measured.fringe_axis,
                                        mm_per_unit=1e-3 / rig.scale_to_m)
            out.setdefault(f"sphere_rms_um_{region}", {})[label] = rms
            out.setdefault(f"sphere_radius_{region}", {})[label] = radius
    return out


def write_report(diagnosis, out_dir, *, rerender: bool = True) -> dict:
    """Write everything into ``out_dir`` (created); returns the ``report.json`` content."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    measured, reference = diagnosis.measured, diagnosis.reference
    report = {"cause": diagnosis.cause, "effects": _entries(diagnosis)}
    if diagnosis.additional:
        report["additional_effects"] = [
            {k: e[k] for k in ("name", "parameters", "residual_before", "residual_after", "gain", "evidence")}
            for e in diagnosis.additional]
    figures = {}
    # the extended rig: the baseline rig plus the named effects
    extended = list(diagnosis.extended_effects)
    if diagnosis.rig is not None:
        path = save_rig(replace(diagnosis.rig, effects=tuple(extended)), out_dir / "extended_rig.yaml")
    else:
        path = out_dir / "extended_effects.yaml"
        path.write_text(yaml.safe_dump({"effects": extended}, sort_keys=False))
    report["extended_rig"] = str(path)
    if diagnosis.corrected_rig is not None:  # the fitted calibration_error: the rig the data were taken with
        corrected = save_rig(replace(diagnosis.corrected_rig, effects=()), out_dir / "corrected_rig.yaml")
        report["corrected_rig"] = str(corrected)
        if reference.kind == "sphere":
            report["corrected_calibration"] = _corrected_sphere(diagnosis)
    report["reference"] = reference.label
    report["measured"] = str(measured.source)
    decomposition = {}
    if diagnosis.registration is not None:
        registration = diagnosis.registration
        report["registration"] = {"pose": registration.pose, "rms_px": registration.rms_px,
                                  "pixels": registration.pixels,
                                  "order_errors_fraction": registration.order_errors,
                                  "geometry_pose": diagnosis.geometry.pose,
                                  "geometry_rms_px": diagnosis.geometry.rms_px}
        if registration.pose_change is not None:
            report["registration"]["pose_change"] = registration.pose_change
        residual = measured.projector_x - registration.model_x  # measured - twin, every valid pixel
        phase = decompose_phase(residual, measured.projector_x, frequency=measured.frequency, extent=measured.extent)
        decomposition["phase"] = phase["stats"]
        figures["phase_residual"] = map_figure(out_dir / "phase_residual.png", {"measured - twin": residual},
                                               unit="proj px").name
        if phase["maps"]:
            figures["phase_decomposition"] = map_figure(out_dir / "phase_decomposition.png", phase["maps"],
                                                        unit="proj px").name
            figures["phase_periodic"] = profile_figure(
                out_dir / "phase_periodic.png", {"periodic part": phase["stats"]["periodic_profile_px"]},
                x_label="wrapped phase 0..2pi", unit="proj px").name
    if diagnosis.pixels is not None and diagnosis.residual_before is not None:
        pixels = diagnosis.pixels
        shape = measured.frames[0].shape[1:]
        before = np.sqrt(np.mean(np.concatenate(diagnosis.residual_before) ** 2, axis=0))
        after = np.sqrt(np.mean(np.concatenate(diagnosis.residual_after) ** 2, axis=0))
        figures["intensity_residual"] = map_figure(
            out_dir / "intensity_residual.png",
            {"RMS measured - twin": _image(shape, pixels.index, before),
             "after the cause": _image(shape, pixels.index, after)}, unit="DN").name
        intensity = decompose_intensity(pixels, diagnosis.residual_before, diagnosis.model_before)
        decomposition["intensity"] = intensity["stats"]
        profiles = {f"{k}: residual / modulation": v["profile"] for k, v in intensity["stats"]["periodic"].items()}
        profiles["per frame: mean residual / mean level"] = intensity["stats"]["per_frame_relative"]
        profiles["by model level (DN)"] = intensity["stats"]["by_level"]["mean_residual_dn"]
        figures["intensity_decomposition"] = profile_figure(out_dir / "intensity_decomposition.png", profiles,
                                                            x_label="angle / frame / level", unit="").name
    report["decomposition"] = decomposition
    if diagnosis.residual_before is not None:
        def rms(parts) -> float:
            return float(np.sqrt(np.mean(np.concatenate([p.ravel() for p in parts]) ** 2)))

        report["residual_rms_dn"] = {"twin": rms(diagnosis.residual_before),
                                     "extended_twin": rms(diagnosis.residual_after),
                                     "pixels": diagnosis.pixels.size}
    if rerender:
        again = _rerender(diagnosis, extended)
        if "sphere_rms_um" in again:
            report["sphere_rms_um"] = again.pop("sphere_rms_um")
            report["sphere_rms_um_whole"] = again.pop("sphere_rms_um_whole")
        report["rerender"] = again
    report["figures"] = figures
    report = json_ready(report)
    (out_dir / "report.json").write_text(json.dumps(report, indent=2))
    (out_dir / "report.md").write_text(_markdown(report))
    return report


def _markdown(report: dict) -> str:
    lines = ["# Sim-to-real diagnosis", "", f"- measured: `{report['measured']}`",
             f"- reference: `{report['reference']}`", f"- **cause: {report['cause']}**",
             f"- extended rig: `{report['extended_rig']}`", ""]
    if "registration" in report:
        r = report["registration"]
        lines += [f"Registration: pose {r['pose']}, phase RMS {r['rms_px']} projector px over {r['pixels']} pixels.",
                  ""]
        if "pose_change" in r:
            change = r["pose_change"]
            lines += [f"Scene pose change (about its centroid): rotation {change['rotation_deg']} deg about "
                      f"{change['rotation_axis']}, centroid moved by {change['centroid_translation']}.", ""]
    lines += ["## Candidates, ranked", "",
              "| effect | named | parameters | residual before | after | gain | dBIC | domain |",
              "|---|---|---|---|---|---|---|---|"]
    for e in report["effects"]:
        ev = e["evidence"]
        params = ", ".join(f"{k}={v}" for k, v in e["parameters"].items())
        lines.append(f"| {e['name']} | {'yes' if ev['named'] else 'no'} | {params} | {e['residual_before']} | "
                     f"{e['residual_after']} | {e['gain']} | {ev['delta_bic']} | {ev['domain']} ({ev['unit']}) |")
    lines.append("")
    for e in report.get("additional_effects", []):
        lines.append(f"Also named (round {e['evidence'].get('round')}, on top of the cause): **{e['name']}** "
                     f"{e['parameters']}, residual {e['residual_before']} -> {e['residual_after']} "
                     f"(gain {e['gain']}).")
    if report.get("additional_effects"):
        lines.append("")
    if "sphere_rms_um" in report:
        s = report["sphere_rms_um"]
        lines += ["## Sphere-fit RMS (um)", "", "| pixels | measured | twin | extended twin |", "|---|---|---|---|",
                  f"| interior | {s['measured']} | {s['twin']} | {s['extended_twin']} |"]
        w = report.get("sphere_rms_um_whole")
        if w:
            lines.append(f"| whole sphere | {w['measured']} | {w['twin']} | {w['extended_twin']} |")
        lines.append("")
    if "corrected_calibration" in report:
        c = report["corrected_calibration"]
        lines += [f"## The corrected calibration (`{report['corrected_rig']}`) on the measured phase", "",
                  "| pixels | RMS given (um) | RMS corrected (um) | radius given | radius corrected |",
                  "|---|---|---|---|---|"]
        lines += [f"| {region} | {c[f'sphere_rms_um_{region}']['given']} | {c[f'sphere_rms_um_{region}']['corrected']} "
                  f"| {c[f'sphere_radius_{region}']['given']} | {c[f'sphere_radius_{region}']['corrected']} |"
                  for region in ("interior", "whole")]
        lines += ["", f"Certified radius: {c['certified_radius']}.", ""]
    if report.get("rerender"):
        lines += ["## Rendered again", "", "```json", json.dumps(report["rerender"], indent=2), "```", ""]
    phase = report.get("decomposition", {}).get("phase")
    if phase:
        keys = [k for k in phase if k.endswith("_rms_px")]
        lines += ["## Phase residual decomposition (projector px)", "", "| component | RMS |", "|---|---|"]
        lines += [f"| {k[:-7]} | {phase[k]} |" for k in keys]
        lines += ["", f"Periodic harmonics 1-4 (px): {phase.get('periodic_harmonics_px')}; neighbour correlation "
                       f"of the random part: {phase.get('random_neighbour_correlation')}", ""]
    intensity = report.get("decomposition", {}).get("intensity")
    if intensity:
        lines += ["## Intensity residual decomposition (DN)", "",
                  f"Total RMS {intensity['total_rms_dn']} DN, random part {intensity['random_rms_dn']} DN.", ""]
        for k, v in intensity["periodic"].items():
            lines.append(f"- {k}: harmonics 1-4 of residual/modulation {v['harmonics_relative']}")
        lines.append("")
    for name, file in report.get("figures", {}).items():
        lines += [f"### {name}", "", f"![{name}]({file})", ""]
    return "\n".join(lines)
