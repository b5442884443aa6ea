"""The diagnosis' parts against analytic answers: BIC, the noise fit, the phase decomposition, the analytic
reference surface against the twin's ray cast, and the forward model against the twin's renderer."""
import numpy as np
import pytest

from dptpu.sim.diagnosis.noise import QUANTIZATION_VAR_DN2, fit_sensor_noise
from dptpu.sim.diagnosis.reference import parse_reference, surface_hits
from dptpu.sim.diagnosis.residuals import decompose_phase, harmonics
from dptpu.sim.diagnosis.selection import delta_bic, gain
from dptpu.sim.raycast import trace
from dptpu.sim.rig import load_twin_rig, working_point
from dptpu.sim.scenes import sphere_scene


def test_delta_bic_and_gain_formulas():
    # n log(RSS0/RSS) - k log n
    assert delta_bic(200.0, 100.0, 1000, 2) == pytest.approx(1000 * np.log(2.0) - 2 * np.log(1000))
    assert gain(2.0, 0.5) == pytest.approx(0.75)
    assert delta_bic(100.0, 100.0, 1000, 1) < 0  # no improvement: the penalty alone


def test_noise_fit_recovers_read_and_shot_noise():
    rng = np.random.default_rng(0)
    level = rng.uniform(20.0, 200.0, (12, 20000))  # (N, P) model levels, DN
    read, shot = 1.5, 0.05
    sigma = np.sqrt(QUANTIZATION_VAR_DN2 + read ** 2 + shot * level)
    residual = rng.normal(0.0, 1.0, level.shape) * sigma * np.sqrt(11.0 / 12.0)  # one gain per pixel fitted
    entry = fit_sensor_noise([residual], [level])
    assert entry["parameters"]["read_noise_dn"] == pytest.approx(read, rel=0.05)
    assert entry["parameters"]["gain_dn_per_electron"] == pytest.approx(shot, rel=0.05)
    assert entry["evidence"]["delta_bic"] > 1e4
    quantization = rng.uniform(-0.5, 0.5, level.shape) * np.sqrt(11.0 / 12.0)  # rounding only, gain fitted
    quiet = fit_sensor_noise([quantization], [level])
    assert quiet["parameters"]["read_noise_dn"] < 0.1
    assert quiet["evidence"]["delta_bic"] < 10


def test_phase_decomposition_separates_radial_periodic_and_random():
    height, width, frequency, extent = 120, 160, 96.0, 912.0
    v, u = np.mgrid[0:height, 0:width].astype(float)
    x = (u - (width - 1) / 2) / (width / 2)
    y = (v - (height - 1) / 2) / (height / 2)
    projector_x = 200.0 + 3.1 * u + 0.37 * v  # ~3 projector px per camera px
    theta = 2 * np.pi * frequency * projector_x / extent
    radial = 0.05 * (x * x + y * y) ** 2  # r^4: not a quadratic, so the low-order part leaves it
    periodic = 0.02 * np.cos(theta)
    noise = np.random.default_rng(1).normal(0.0, 0.01, u.shape)
    result = decompose_phase(radial + periodic + noise, projector_x, frequency=frequency, extent=extent)["stats"]
    assert result["periodic_harmonics_px"][0] == pytest.approx(0.02, rel=0.1)
    assert result["periodic_harmonics_px"][1] < 0.003
    assert result["random_rms_px"] == pytest.approx(0.01, rel=0.1)
    assert abs(result["random_neighbour_correlation"]) < 0.05  # white
    assert result["radial_rms_px"] > 0.005


def test_harmonics_of_a_cosine():
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    np.testing.assert_allclose(harmonics(0.3 * np.cos(2 * t) + 0.1 * np.sin(t)), [0.1, 0.3, 0.0, 0.0], atol=1e-12)


def test_analytic_sphere_matches_the_twin_ray_cast():
    """The registration's exact sphere against the raycast of the twin's mesh (7 subdivisions: facets within
    0.45 um): same lit pixels away from the rim, projector coordinates within 0.01 px."""
    rig = load_twin_rig("nominal", size="160x120")
    center = working_point(rig)
    reference = parse_reference("sphere:50.8082")
    hits = surface_hits(rig, "sphere", center, diameter=reference.diameter)
    samples = trace(rig, sphere_scene(rig, center=center, subdivisions=7).meshes)
    both = hits.lit & samples.lit
    assert both.sum() > 1000
    assert (hits.lit ^ samples.lit).sum() < 0.05 * both.sum()
    difference = hits.projector_xy[both] - samples.projector_xy[both]
    assert np.abs(difference).max() < 0.01


@pytest.mark.parametrize("text, message", [("sphere:abc", "diameter > 0"), ("box", "must be sphere"),
                                           ("sphere:0", "diameter > 0")])
def test_bad_reference_names_the_option(text, message):
    with pytest.raises(ValueError, match=message):
        parse_reference(text)


def test_projector_response_is_the_piecewise_linear_table():
    from dptpu.sim.effects import parse_effects
    from dptpu.sim.effects.pattern import pattern_levels

    table = [0.0, 0.1, 0.5, 0.9, 1.0]  # at inputs 0, 0.25, 0.5, 0.75, 1
    effects = parse_effects([{"projector_response": {"levels": table}}])
    # coordinates 0, 0.5, 1 of one period over 4 px: levels 1, 0.5 + 0.5 cos(pi/4), 0.5
    out = pattern_levels(np.array([0.0, 0.5, 1.0]), frequency=1, extent=4, shift=0.0, offset=0.5, amplitude=0.5,
                         effects=effects)
    p = 0.5 + 0.5 * np.cos(np.pi / 4)
    np.testing.assert_allclose(out, [1.0, 0.9 + (p - 0.75) / 0.25 * 0.1, 0.5], atol=1e-12)
    with pytest.raises(ValueError, match=r"projector_response.levels: must be a non-decreasing list"):
        parse_effects([{"projector_response": {"levels": [0.5, 0.2]}}])
