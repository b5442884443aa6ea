"""Each effect changes frames exactly as docs/effects.md says, and every effect is off by default."""
from dataclasses import replace

import numpy as np
import pytest
import yaml

from dptpu.sim.effects import EFFECTS, STAGES, load_effects, parse_effects
from dptpu.sim.effects.camera import apply_camera_effects, vignetting_factor
from dptpu.sim.effects.geometry import render_rig
from dptpu.sim.effects.pattern import defocus_attenuation
from dptpu.sim.effects.phase import phase_filter
from dptpu.sim.image_formation import DEFAULT_AMPLITUDE as A
from dptpu.sim.image_formation import DEFAULT_OFFSET as O
from dptpu.sim.image_formation import SequenceSpec, reflectance_factor, render_frames, render_frames_float
from dptpu.sim.raycast import trace
from dptpu.sim.scenes import load_scene
from dptpu.sim.scenes.scene import posed_mesh

W, FS = 912, 255.0
SEQ = [SequenceSpec(96, 12)]


def _harmonics(frames):
    """Complex amplitudes (N//2+1, H, W) of the frames over the steps: |c_1| = B/2 of I = A + B cos(.)."""
    return np.fft.rfft(frames, axis=0) / frames.shape[0]


def _render(rig, samples, effects, sequences=SEQ, seed=0):
    return render_frames_float(rig, samples, sequences, effects=effects, seed=seed)[0]


def test_every_effect_is_off_by_default(small_rig, plane_samples):
    assert small_rig.effects == ()
    ideal = _render(small_rig, plane_samples, None)
    np.testing.assert_array_equal(ideal, _render(small_rig, plane_samples, []))
    theta = 2 * np.pi * 96 * plane_samples.projector_xy[..., 0] / W
    factor = reflectance_factor(small_rig, plane_samples)
    np.testing.assert_allclose(ideal[5], FS * factor * (O + A * np.cos(theta - 2 * np.pi * 5 / 12)), atol=1e-9)
    for name, spec in EFFECTS.items():
        assert {e.name for e in parse_effects([name])} == {name}
        assert spec.stage in STAGES and spec.summary
        if name in ("phase_filter", "motion", "lens_distortion", "calibration_error", "pixel_footprint"):
            continue  # not a frame change here (decoder stage / zero motion / zero extra / acts in the trace)
        changed = _render(small_rig, plane_samples, [name])
        assert np.abs(changed - ideal).max() > 0.5, name


def test_rig_effects_list_switches_effects_on(small_rig, plane_samples):
    rig = replace(small_rig, effects=({"projector_gamma": {"gamma": 2.0}},))
    np.testing.assert_array_equal(_render(rig, plane_samples, None),
                                  _render(small_rig, plane_samples, [{"name": "projector_gamma", "gamma": 2.0}]))


def test_projector_gamma_creates_the_expected_second_harmonic(small_rig, plane_samples):
    # (O + A cos t)^2 = O^2 + A^2/2 + 2 O A cos t + A^2/2 cos 2t: harmonic 2 / harmonic 1 = A / (4 O)
    c = _harmonics(_render(small_rig, plane_samples, [{"projector_gamma": {"gamma": 2.0}}]))
    ratio = np.abs(c[2]) / np.abs(c[1])
    np.testing.assert_allclose(ratio, A / (4 * O), rtol=1e-9)
    ideal = _harmonics(_render(small_rig, plane_samples, []))
    assert np.abs(ideal[2]).max() < 1e-9 * np.abs(ideal[1]).max()


@pytest.mark.parametrize("gamma", [1.0, 2.2])
def test_projector_defocus_attenuates_modulation_by_the_gaussian_factor(small_rig, plane_samples, gamma):
    sigma = 1.3
    base = [{"projector_gamma": {"gamma": gamma}}]
    sharp = _harmonics(_render(small_rig, plane_samples, base))
    blurred = _harmonics(_render(small_rig, plane_samples, base + [{"projector_defocus": {"sigma_px": sigma}}]))
    # 12 steps alias harmonics 11 and 13 onto 1 (10 and 14 onto 2): with gamma 2.2 they weigh ~1e-5
    for k in (0, 1, 2):
        expected = defocus_attenuation(sigma, 96, W, k)
        if np.abs(sharp[k]).max() < 1e-6:
            continue
        np.testing.assert_allclose(np.abs(blurred[k]) / np.abs(sharp[k]), expected, rtol=1e-9 if gamma == 1 else 1e-4)
    assert defocus_attenuation(sigma, 96, W) == pytest.approx(np.exp(-2 * np.pi ** 2 * sigma ** 2 * 96 ** 2 / W ** 2))


def test_phase_shift_error_shifts_each_step(small_rig, plane_samples):
    errors = [0.1 * ((-1) ** n) for n in range(12)]
    effect = {"phase_shift_error": {"scale": 1.02, "errors_rad": errors, "sigma_rad": 0.0}}
    frames = _render(small_rig, plane_samples, [effect])
    theta = 2 * np.pi * 96 * plane_samples.projector_xy[..., 0] / W
    factor = reflectance_factor(small_rig, plane_samples)
    for n in (0, 3, 7):
        shift = -2 * np.pi * n / 12 * 1.02 + errors[n]
        np.testing.assert_allclose(frames[n], FS * factor * (O + A * np.cos(theta + shift)), atol=1e-9)
    with pytest.raises(ValueError, match="one error per step"):
        _render(small_rig, plane_samples, [{"phase_shift_error": {"errors_rad": [0.1, 0.2]}}])


def test_projector_pixelation_holds_the_level_over_each_micromirror(small_rig, plane_samples):
    frames = _render(small_rig, plane_samples, [{"projector_pixelation": {"quantize_bits": 8}}])
    x_pixel = np.round(plane_samples.projector_xy[..., 0])
    factor = reflectance_factor(small_rig, plane_samples)
    level = np.round(255 * (O + A * np.cos(2 * np.pi * 96 * x_pixel / W - 2 * np.pi * 4 / 12))) / 255
    np.testing.assert_allclose(frames[4], FS * factor * level, atol=1e-9)


def test_lens_distortion_is_rendered_but_not_calibrated(small_rig):
    effects = parse_effects([{"lens_distortion": {"camera": [0.05, 0, 0, 0, 0], "projector": [0, 0, 0.001, 0, 0]}}])
    distorted = render_rig(small_rig, effects)
    np.testing.assert_allclose(distorted.camera.dist, small_rig.camera.dist + [0.05, 0, 0, 0, 0])
    np.testing.assert_allclose(distorted.projector.dist, small_rig.projector.dist + [0, 0, 0.001, 0, 0])
    assert render_rig(small_rig, ()) is small_rig


def test_motion_frame_g_sees_the_scene_moved_g_times(small_rig):
    scene = load_scene("plane", small_rig)
    vertices = np.array([[-15, -15, 0], [15, -15, 0], [15, 15, 0], [-15, 15, 0]], float)
    square = posed_mesh("square", vertices, [[0, 2, 1], [0, 3, 2]], translation=[0, 0, 760])
    meshes = [scene.meshes[0], square]
    samples = trace(small_rig, meshes)
    velocity = [2.0, 0.0, 0.0]
    moving = _render(small_rig, samples, [{"motion": {"velocity_per_frame": velocity}}], [SequenceSpec(16, 3)])
    for g in (0, 2):
        moved = [meshes[0], posed_mesh("square", square.vertices, square.triangles,
                                       translation=np.multiply(velocity, g) + [0, 0, 0])]
        # the plane moves too (it only slides along itself and is larger than the view)
        moved[0] = posed_mesh("plane", meshes[0].vertices, meshes[0].triangles, translation=np.multiply(velocity, g),
                              material=meshes[0].material)
        static = render_frames_float(small_rig, trace(small_rig, moved), [SequenceSpec(16, 3)])[0]
        np.testing.assert_allclose(moving[g], static[g], atol=1e-6)
    assert np.abs(moving[2] - _render(small_rig, samples, [], [SequenceSpec(16, 3)])[2]).max() > 10


def test_ambient_light_adds_level_times_albedo(small_rig, plane_samples):
    ideal = _render(small_rig, plane_samples, [])
    lit = _render(small_rig, plane_samples, [{"ambient_light": {"level": 0.1, "background": 0.02}}])
    expected = FS * (0.1 * plane_samples.albedo.astype(float) + 0.02)
    np.testing.assert_allclose(lit - ideal, np.broadcast_to(expected, lit.shape), rtol=1e-9)


def test_vignetting_scales_background_and_modulation_alike(small_rig, plane_samples):
    ideal = _render(small_rig, plane_samples, [])
    dark = _render(small_rig, plane_samples, [{"vignetting": {"k1": -0.3, "k2": 0.05}}])
    factor = vignetting_factor((120, 160), -0.3, 0.05)
    np.testing.assert_allclose(dark, ideal * factor, rtol=1e-12)
    r2_corner = (79.5 ** 2 + 59.5 ** 2) / (80.0 ** 2 + 60.0 ** 2)  # pixel centres; r = 1 at the image corner
    assert factor.min() == pytest.approx(1 - 0.3 * r2_corner + 0.05 * r2_corner ** 2, abs=1e-12)
    assert factor.max() == pytest.approx(1.0, abs=1e-4)
    np.testing.assert_allclose(np.angle(_harmonics(dark)[1]), np.angle(_harmonics(ideal)[1]), atol=1e-12)


def test_camera_defocus_attenuates_camera_fringes_by_the_gaussian_factor():
    period, sigma = 16.0, 1.5
    u = np.arange(256)
    image = np.broadcast_to(100 + 50 * np.cos(2 * np.pi * u / period), (64, 256))[None].copy()
    blurred = apply_camera_effects(image, effects=parse_effects([{"camera_defocus": {"sigma_px": sigma}}]),
                                   albedo=np.ones((64, 256)), hit=np.ones((64, 256), bool), full_scale=FS,
                                   exposure=1.0, rng=np.random.default_rng(0))[0]
    amplitude = np.abs(np.fft.rfft(blurred[32, 64:192]))[8] / 64
    assert amplitude / 50 == pytest.approx(np.exp(-2 * np.pi ** 2 * sigma ** 2 / period ** 2), rel=2e-3)


def test_intensity_drift_scales_frame_n_by_one_plus_rate_n(small_rig, plane_samples):
    ideal = _render(small_rig, plane_samples, [])
    drift = _render(small_rig, plane_samples, [{"intensity_drift": {"rate_per_frame": 0.02}}])
    np.testing.assert_allclose(drift, ideal * (1 + 0.02 * np.arange(12))[:, None, None], rtol=1e-12)


def test_sensor_noise_is_poisson_gaussian_with_the_documented_variance():
    signal = np.full((1, 400, 500), 100.0)
    effects = parse_effects([{"sensor_noise": {"read_noise_dn": 2.0, "gain_dn_per_electron": 0.5, "dark_dn": 4.0}}])
    noisy = apply_camera_effects(signal, effects=effects, albedo=np.ones((400, 500)), hit=np.ones((400, 500), bool),
                                 full_scale=FS, exposure=1.0, rng=np.random.default_rng(1))
    assert noisy.mean() == pytest.approx(104.0, abs=0.05)
    assert noisy.var() == pytest.approx(0.5 * 104.0 + 4.0, rel=0.02)


def test_saturation_clips_the_amplified_signal(small_rig, plane_samples):
    ideal = _render(small_rig, plane_samples, [])
    clipped = _render(small_rig, plane_samples, [{"saturation": {"exposure_gain": 1.5, "level": 0.9}}])
    np.testing.assert_allclose(clipped, np.minimum(1.5 * ideal, 0.9 * FS), rtol=1e-12)
    assert (clipped == 0.9 * FS).mean() > 0.05


def test_phase_filter_keeps_a_ramp_and_averages_noise():
    v, u = np.mgrid[0:128, 0:128]
    ramp = np.mod(0.3 * u + 0.1 * v, 2 * np.pi)
    smooth = phase_filter(ramp, 2.0)
    inner = (slice(12, -12), slice(12, -12))
    assert np.abs(np.angle(np.exp(1j * (smooth - ramp))))[inner].max() < 1e-3
    noise = np.random.default_rng(2).normal(0, 0.05, ramp.shape)
    filtered = phase_filter(np.mod(ramp + noise, 2 * np.pi), 2.0)
    residual = np.angle(np.exp(1j * (filtered - ramp)))[inner]
    assert residual.std() == pytest.approx(0.05 / (2 * np.sqrt(np.pi) * 2.0), rel=0.15)


def test_renders_are_deterministic_for_a_seed(small_rig, plane_samples):
    effects = [{"sensor_noise": {"read_noise_dn": 2.0}}, {"phase_shift_error": {"sigma_rad": 0.05}},
               {"intensity_drift": {"rate_per_frame": 0.0, "sigma": 0.01}}]
    a = render_frames(small_rig, plane_samples, SEQ, effects=effects, seed=3)[0]
    b = render_frames(small_rig, plane_samples, SEQ, effects=effects, seed=3)[0]
    c = render_frames(small_rig, plane_samples, SEQ, effects=effects, seed=4)[0]
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)


@pytest.mark.parametrize("entries, message", [
    (["fog"], r"E.yaml: effects\[0\]: unknown effect 'fog'; expected one of phase_shift_error"),
    ([{"projector_gamma": {"gama": 2}}], r"effects\[0\].projector_gamma.gama: unknown parameter; projector_gamma "
                                          r"takes gamma"),
    ([{"projector_gamma": {"gamma": -1}}], r"effects\[0\].projector_gamma.gamma: must be a number > 0; got -1"),
    ([{"lens_distortion": {"camera": [1, 2]}}], r"lens_distortion.camera: must be a list of 5 numbers"),
    (["vignetting", "vignetting"], "effect 'vignetting' is listed twice"),
])
def test_bad_effects_yaml_names_file_key_and_expected_value(tmp_path, entries, message):
    path = tmp_path / "E.yaml"
    path.write_text(yaml.safe_dump({"effects": entries}))
    with pytest.raises(ValueError, match=message):
        load_effects(path)


def test_effects_are_applied_in_canonical_stage_order():
    names = [e.name for e in parse_effects(["sensor_noise", "phase_filter", "projector_gamma", "motion"])]
    assert names == ["projector_gamma", "motion", "sensor_noise", "phase_filter"]


def test_projector_images_for_blender_follow_the_pattern_conventions_and_effects():
    from dptpu.fpp.patterns import fringe_patterns
    from dptpu.sim.effects.pattern import projector_images

    kwargs = dict(frequency=10.9, steps=4, axis="y", shift_sign=-1, projector_size=(64, 48), offset=O, amplitude=A)
    ideal = projector_images(**kwargs)
    reference = fringe_patterns(frequency=10.9, steps=4, projector_size=(64, 48), axis="y", dtype=float) / 255
    np.testing.assert_allclose(ideal, reference, atol=1e-12)
    gamma = projector_images(**kwargs, effects=parse_effects([{"projector_gamma": {"gamma": 2.2}}]))
    np.testing.assert_allclose(gamma, reference ** 2.2, atol=1e-12)
    with pytest.raises(ValueError, match="raycast-only"):
        projector_images(**kwargs, effects=parse_effects([{"projector_defocus": {"focus_distance": 800.0}}]))
