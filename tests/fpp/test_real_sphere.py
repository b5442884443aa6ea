"""The real DP-TPU sphere: the paper's Fig. 3 reproduced, and the project's own reconstruction's goals."""
import numpy as np
import pytest

from dptpu.fpp import real_sphere


@pytest.fixture(scope="module")
def report(sphere_dir):
    return real_sphere.evaluate(sphere_dir)


def test_paper_method_reproduces_fig3_figures_to_10_nm(report):
    # The figures of Fig. 3, each reproduced to 0.01 um by the paper's own script. For the REAL phase the
    # figure's calibration labels are swapped: 58.541 um comes from the twin calibration and 61.999 um from the
    # real one (docs/real-sphere.md); the twin phase's labels hold.
    computed = report["paper"]
    assert abs(computed["calib_real_phase_real"] - 61.999) < 0.01
    assert abs(computed["calib_twin_phase_real"] - 58.541) < 0.01
    assert abs(computed["calib_real_phase_twin"] - 32.125) < 0.01
    assert abs(computed["calib_twin_phase_twin"] - 28.256) < 0.01


def test_fig3_labels_for_the_real_phase_are_swapped(report):
    labelled = report["paper_figures_um"]
    computed = report["paper"]
    assert abs(computed["calib_real_phase_real"] - labelled["calib_twin_phase_real"]) < 0.01
    assert abs(computed["calib_twin_phase_real"] - labelled["calib_real_phase_real"]) < 0.01


def test_own_reconstruction_real_phase_real_calibration(report):
    ours = report["ours"]["calib_real_phase_real"]
    assert ours["points"] == 16796  # every valid pixel of the paper's rule |phase| >= 10
    # Pose refined over all nine views, distortion-aware triangulation, geometric fit: 39.50 um against the
    # paper method's 62.00 um on the same points (goal <= 47 um; docs/real-sphere.md has the step-by-step table).
    assert ours["rms_um"] <= 47.0
    assert abs(ours["rms_um"] - 39.50) < 0.05
    assert abs(ours["radius_mm"] - 25.4041) < 0.03  # certified radius within 30 um
    edge = ours["edge_band_removed"]
    assert edge["rms_um"] <= 35.0  # goal for a principled edge-band rule (incidence <= 70 deg)
    assert abs(edge["rms_um"] - 26.69) < 0.05
    assert edge["points"] == 15329  # the rule keeps 91.3 % of the points
    assert abs(edge["radius_mm"] - 25.4041) < 0.005


def test_each_calibration_reconstructs_its_own_phase_best(report):
    ours = report["ours"]
    assert ours["calib_real_phase_real"]["rms_um"] < ours["calib_twin_phase_real"]["rms_um"]
    assert ours["calib_twin_phase_twin"]["rms_um"] < ours["calib_real_phase_twin"]["rms_um"]
    assert ours["calib_twin_phase_twin"]["rms_um"] < 16.0  # the twin is consistent with itself (paper: 28.3)


def test_own_reconstruction_beats_the_paper_method_where_distortion_is_real(report):
    # The real calibration carries real lens distortion: correcting it must lower the fit RMS on the real phase.
    assert report["ours"]["calib_real_phase_real"]["rms_um"] < report["paper"]["calib_real_phase_real"] - 10


def test_phase_loader_applies_the_papers_validity_rule(sphere_dir):
    phase = real_sphere.load_phase(sphere_dir, "real")
    assert phase.shape == (480, 640)
    assert np.isfinite(phase).sum() == 16796
    assert np.nanmin(np.abs(phase)) >= 10
