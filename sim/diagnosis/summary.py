"""The few lines ``dptpu twin diagnose`` ends with: the cause, the named effects with their gains, the figures
of the re-render; everything else stays in ``report.json`` (:func:`dptpu.sim.diagnosis.report.write_report`)."""
from __future__ import annotations

__all__ = ["human_summary", "format_parameters"]

#: Parameters shown per effect (the rest is in report.json); an effect not listed shows all of its own.
_SHOWN = {"lens_distortion": ("camera",), "intensity_drift": ("rate_per_frame", "sigma"),
          "phase_shift_error": ("scale",), "sensor_noise": ("read_noise_dn", "gain_dn_per_electron"),
          "saturation": ("exposure_gain", "level"), "projector_response": ("levels",)}


def _number(value) -> str:
    if isinstance(value, (list, tuple)):
        shown = [_number(v) for v in value[:12]]
        return "[" + ", ".join(shown) + (", ..." if len(value) > 12 else "") + "]"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    return f"{value:.4g}"


def format_parameters(name: str, parameters: dict) -> str:
    """``key=value`` pairs of an effect's main parameters, 4 significant digits."""
    keys = _SHOWN.get(name, tuple(parameters))
    if name == "lens_distortion":  # the fitted camera k1 alone
        return f"camera k1={_number(parameters['camera'][0])}"
    return " ".join(f"{k}={_number(parameters[k])}" for k in keys if k in parameters)


def _triple(values: dict, unit: str) -> str:
    parts = [f"{key.replace('_', ' ')} {values[key]:.4g}" for key in ("measured", "twin", "extended_twin")
             if values.get(key) is not None]
    return " / ".join(parts) + f" {unit}"


def human_summary(report: dict, extended_effects) -> str:
    """The summary of a ``report.json`` content and the extended twin's effects (``Diagnosis.extended_effects``,
    entries ``{name: {parameters}}``), as text lines without a trailing newline."""
    lines = [f"cause: {report['cause']}"]
    extension = {next(iter(effect)) for effect in extended_effects}
    entries = report["effects"] + report.get("additional_effects", [])
    extended = [e for e in entries if e["name"] in extension and e["evidence"].get("named", True)]
    extended = [e for i, e in enumerate(extended) if e["name"] not in {x["name"] for x in extended[:i]}]
    if extended:
        lines.append("in the extended twin (gain = share of the twin's residual RMS the effect removes):")
        width = max(len(e["name"]) for e in extended)
        for e in extended:
            shown = format_parameters(e["name"], e["parameters"])
            lines.append(f"  {e['name']:<{width}}  gain {e['gain']:.3f}  {shown}")
    else:
        lines.append("in the extended twin: nothing (no effect of the vocabulary explains the data better than the "
                     "twin)")
    alone = [e for e in report["effects"] if e["evidence"].get("named") and e["name"] not in extension]
    if alone:
        lines.append("also significant on their own, explained by the above: "
                     + ", ".join(f"{e['name']} (gain {e['gain']:.3f})" for e in alone))
    if "sphere_rms_um" in report:
        lines.append("sphere-fit RMS, interior: " + _triple(report["sphere_rms_um"], "um"))
        if "sphere_rms_um_whole" in report:
            lines.append("sphere-fit RMS, whole sphere (edge band included): "
                         + _triple(report["sphere_rms_um_whole"], "um"))
    rerender = report.get("rerender") or {}
    if "phase_rms_px" in rerender:
        lines.append("phase RMS against the data: " + _triple(rerender["phase_rms_px"], "projector px"))
    if "residual_rms_dn" in report:
        lines.append("intensity residual RMS: " + _triple(report["residual_rms_dn"], "DN"))
    lines.append(f"extended rig: {report['extended_rig']}")
    if "corrected_rig" in report:
        lines.append(f"corrected calibration: {report['corrected_rig']}")
    return "\n".join(lines)
