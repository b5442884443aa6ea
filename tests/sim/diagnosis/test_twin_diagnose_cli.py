"""``dptpu twin diagnose``: files, report.json keys, the extended rig, the re-render, bad input (exit 2)."""
import json

import numpy as np
import pytest

from dptpu.cli.main import main
from dptpu.fpp.calibration import load_rig, save_rig
from dptpu.sim.effects import parse_effects

from .hidden import render_measured


@pytest.fixture(scope="module")
def gamma_sphere(tmp_path_factory):
    """The standard sphere with projector gamma 1.6, diagnosed once through the CLI."""
    root = tmp_path_factory.mktemp("cli")
    folder, rig = render_measured(root / "measured", "sphere", {"projector_gamma": {"gamma": 1.6}}, seed=3)
    rig_path = save_rig(rig, root / "rig.yaml")
    out = root / "out"
    code = main(["twin", "diagnose", "--measured", str(folder), "--rig", str(rig_path), "--reference",
                 "sphere:50.8082", "--max-pixels", "1500", "--rounds", "1", "--out", str(out)])
    return code, out, rig


def test_cli_writes_report_with_the_issue_keys(gamma_sphere):
    code, out, _ = gamma_sphere
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert {"cause", "effects", "extended_rig", "sphere_rms_um"} <= set(report)
    assert report["cause"] == "projector_gamma"
    for entry in report["effects"]:
        assert set(entry) == {"name", "parameters", "residual_before", "residual_after", "gain", "evidence"}
        assert "delta_bic" in entry["evidence"]
    assert abs(report["effects"][0]["parameters"]["gamma"] - 1.6) < 0.02
    # ranked: the named cause first, then by evidence
    assert report["effects"][0]["evidence"]["named"]
    assert set(report["sphere_rms_um"]) == {"measured", "twin", "extended_twin"}
    for figure in report["figures"].values():
        assert (out / figure).stat().st_size > 1000
    assert "![" in (out / "report.md").read_text()


def test_cli_extended_rig_holds_the_fitted_effect_and_its_render_matches(gamma_sphere):
    _, out, rig = gamma_sphere
    report = json.loads((out / "report.json").read_text())
    extended = load_rig(report["extended_rig"])
    effects = parse_effects(list(extended.effects))
    assert [e.name for e in effects] == ["projector_gamma"]
    np.testing.assert_allclose(extended.camera.K, rig.camera.K)
    again = report["rerender"]["intensity_rms_dn"]
    # the baseline twin misses the gamma by ~10 DN; the extended twin renders the data to ~quantization
    assert again["twin"] > 5.0
    assert again["extended_twin"] < 0.5
    assert report["residual_rms_dn"]["extended_twin"] < 0.1 * report["residual_rms_dn"]["twin"]


def test_cli_summary_gives_the_cause_its_gain_and_the_sphere_rms(gamma_sphere):
    from dptpu.sim.diagnosis.summary import human_summary

    _, out, _ = gamma_sphere
    report = json.loads((out / "report.json").read_text())
    extended = [effect.as_entry() for effect in parse_effects(list(load_rig(report["extended_rig"]).effects))]
    lines = human_summary(report, extended).splitlines()
    assert lines[0] == "cause: projector_gamma"
    cause = report["effects"][0]
    gamma_line = next(line for line in lines if line.strip().startswith("projector_gamma"))
    assert f"gain {cause['gain']:.3f}" in gamma_line
    assert f"gamma={cause['parameters']['gamma']:.4g}" in gamma_line
    rms = report["sphere_rms_um"]
    assert (f"sphere-fit RMS, interior: measured {rms['measured']:.4g} / twin {rms['twin']:.4g} / extended twin "
            f"{rms['extended_twin']:.4g} um") in lines
    assert lines[-1] == f"extended rig: {report['extended_rig']}" or "corrected calibration" in lines[-1]


@pytest.mark.parametrize("argv, message", [
    (["--reference", "cone:3"], "--reference must be"),
    (["--reference", "sphere:-2"], "diameter > 0"),
    ([], "--reference"),
    (["--reference", "plane", "--self-reference"], "either --reference or --self-reference"),
])
def test_cli_bad_arguments_exit_2(gamma_sphere, capsys, argv, message):
    _, out, _ = gamma_sphere
    code = main(["twin", "diagnose", "--measured", str(out.parent / "measured"), "--rig", "nominal",
                 "--out", str(out.parent / "bad"), *argv])
    assert code == 2
    assert message in capsys.readouterr().err


def test_cli_phase_file_without_keys_exits_2(tmp_path, capsys):
    path = tmp_path / "phase.npz"
    np.savez(path, absolute_phase=np.zeros((4, 4)))
    code = main(["twin", "diagnose", "--measured", str(path), "--rig", "nominal", "--reference", "plane",
                 "--out", str(tmp_path / "out")])
    assert code == 2
    assert "missing key(s) frequency, fringe_axis, projector_size" in capsys.readouterr().err
