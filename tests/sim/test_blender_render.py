"""The Blender renderer against exact answers: the analytic plane, the raycast twin, radiometry, determinism.

These run Blender (bpy 4.5, Cycles on the CPU) in its own environment; they skip when it is missing
(``dptpu sim setup-blender`` creates it; ``scripts/dev.sh test`` does so before the tests). Small renders only:
160x120 camera, 4-8 samples, 8-step sequences.
"""

import numpy as np
import pytest

from dptpu.fpp.distortion import distort, normalized_to_pixels
from dptpu.fpp.patterns import fringe_patterns
from dptpu.fpp.phase import wrapped_phase
from dptpu.fpp.tpu import unwrap_mf
from dptpu.fpp.triangulate import camera_rays
from dptpu.sim.blender import BlenderNotInstalledError, blender_python, render
from dptpu.sim.rig import nominal_rig, working_point
from dptpu.sim.scene_mesh import Material, SceneMesh

F_HIGH, F_LOW, STEPS = 64, 1, 8


@pytest.fixture(scope="module")
def blender_env():
    try:
        return blender_python()
    except BlenderNotInstalledError as exc:
        pytest.skip(f"Blender environment missing ({exc})")


@pytest.fixture(scope="module")
def rig():
    """The nominal DP-TPU-like rig at 160x120, camera and projector distortion on (k1 = -0.06, -0.05)."""
    return nominal_rig(camera_size=(160, 120))


def _plane(rig, normal, *, albedo=0.9):
    """A square plane (800 mm) through the rig's working point with unit ``normal``, facing the camera."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    centre = working_point(rig)
    e1 = np.cross(normal, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    vertices = np.array([centre + 400 * (a * e1 + b * e2) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    if np.cross(vertices[1] - vertices[0], vertices[2] - vertices[0]) @ (rig.camera.center - centre) < 0:
        triangles = triangles[:, ::-1]
    return SceneMesh("plane", vertices, triangles, Material(albedo=albedo, roughness=1.0, specular=0.0)), centre, normal


def _plane_hits(rig, centre, normal):
    """Analytic hit points (H, W, 3) of every camera ray (with the camera's distortion) on the plane."""
    rays = camera_rays(rig.camera)  # (H, W, 3)
    t = ((centre - rig.camera.center) @ normal) / (rays @ normal)
    return rig.camera.center + t[..., None] * rays


def _sequences(rig):
    size = rig.projector.size
    return np.concatenate([fringe_patterns(frequency=f, steps=STEPS, projector_size=size, dtype=float) / 255.0
                           for f in (F_HIGH, F_LOW)]).astype(np.float32)  # (2 STEPS, Hp, Wp)


def _decoded_projector_x(rig, frames):
    """Projector column from a 2-frequency sequence: wrapped phases (Eq. 2), MF unwrapping (Eq. 5)."""
    high, low = wrapped_phase(frames[:STEPS]), wrapped_phase(frames[STEPS:2 * STEPS])
    unwrapped = unwrap_mf(high.phase, low.phase, F_HIGH, F_LOW)
    x_p = unwrapped.absolute_phase * rig.projector.size[0] / (2 * np.pi * F_HIGH)
    return x_p, high.modulation


def test_plane_projector_coordinate_and_radiometry_match_the_analytic_answer(blender_env, rig):
    mesh, centre, normal = _plane(rig, [0.1, -0.05, -1.0])
    white = np.ones((1, rig.projector.size[1], rig.projector.size[0]), np.float32)
    result = render(rig, [mesh], np.concatenate([_sequences(rig), white]), samples=4, seed=0)
    assert result.frames.shape == (2 * STEPS + 1, 120, 160) and result.frames.dtype == np.float32
    assert result.render_camera.warp  # the camera's distortion went through the resampling

    points = _plane_hits(rig, centre, normal)  # (H, W, 3)
    local = points @ rig.projector.R.T + rig.projector.T
    expected_xy = normalized_to_pixels(distort(local[..., :2] / local[..., 2:], rig.projector.dist),
                                       rig.projector.K)
    x_p, modulation = _decoded_projector_x(rig, result.frames)
    error = x_p - expected_xy[..., 0]
    assert np.all(np.isfinite(error))
    assert abs(np.mean(error)) < 0.01  # no systematic offset (projector pixels; measured 0.003)
    assert np.median(np.abs(error)) < 0.1  # sampling noise of 4 samples per pixel (measured 0.058)
    assert np.percentile(np.abs(error), 99) < 0.4

    # white frame: a Lambertian pixel reads albedo * cos(incidence) * (d_ref / d)^2 (render.py's radiometry)
    to_projector = rig.projector.center - points
    distance = np.linalg.norm(to_projector, axis=-1)
    cos_incidence = np.abs(to_projector @ normal) / distance
    d_ref = np.linalg.norm(working_point(rig) - rig.projector.center)
    expected = 0.9 * cos_incidence * (d_ref / distance) ** 2
    np.testing.assert_allclose(result.frames[-1], expected, rtol=0.01)


def test_ambient_light_reads_albedo_times_ambient(blender_env, rig):
    mesh, _, _ = _plane(rig, [0.0, 0.0, -1.0], albedo=0.5)
    black = np.zeros((1, rig.projector.size[1], rig.projector.size[0]), np.float32)
    frames = render(rig, [mesh], black, samples=4, ambient=0.4).frames
    assert np.median(frames[0]) == pytest.approx(0.5 * 0.4, rel=0.02)


def test_render_is_deterministic_for_a_seed(blender_env):
    rig = nominal_rig(camera_size=(80, 60))
    mesh, _, _ = _plane(rig, [0.2, 0.1, -1.0])
    pattern = (fringe_patterns(frequency=16, steps=3, projector_size=rig.projector.size, dtype=float)[:1]
               / 255.0).astype(np.float32)
    first = render(rig, [mesh], pattern, samples=2, seed=7, max_bounces=0).frames
    again = render(rig, [mesh], pattern, samples=2, seed=7, max_bounces=0).frames
    np.testing.assert_array_equal(first, again)
    assert first.std() > 0.05  # fringes, not an empty frame


def test_cross_check_with_the_raycast_twin_on_the_standard_sphere(blender_env, rig):
    """The issue's cross-check: Blender's decoded projector column and the raycast ground truth agree within
    0.2 projector pixels (median over pixels valid in both)."""
    from dptpu.sim.raycast import trace
    from dptpu.sim.scenes import sphere_scene

    scene = sphere_scene(rig, subdivisions=5)
    samples = trace(rig, scene)
    frames = render(rig, scene, _sequences(rig), samples=8, seed=0).frames
    x_p, modulation = _decoded_projector_x(rig, frames)
    both = samples.lit & np.isfinite(x_p) & (modulation > 0.1 * modulation.max())
    assert both.sum() > 0.9 * samples.lit.sum()  # Blender lights and sees what the raycast says is lit
    error = np.abs(x_p - samples.projector_xy[..., 0])[both]
    assert np.median(error) < 0.2  # measured 0.09
    assert np.mean(error > 1.0) < 0.02  # only silhouette pixels disagree by more


def test_textured_board_under_white_light_matches_the_raycast_reflectance(blender_env, rig):
    """Albedo texture through the UVs (orientation, texel centres), smooth normals and falloff as the raycast twin."""
    from dptpu.sim.image_formation import reflectance_factor
    from dptpu.sim.raycast import trace
    from dptpu.sim.scenes import load_scene

    scene = load_scene("board", rig)
    assert scene.meshes[0].albedo_texture is not None
    samples = trace(rig, scene)
    white = np.ones((1, rig.projector.size[1], rig.projector.size[0]), np.float32)
    frame = render(rig, scene, white, samples=4, max_bounces=0).frames[0]
    expected = reflectance_factor(rig, samples)
    difference = np.abs(frame - expected)[samples.lit]
    assert np.median(difference) < 0.02  # measured 0.005 (squares of albedo 0.05 and 0.9)
    assert np.mean(difference > 0.2) < 0.1  # only pixels on a square's edge (area-integrated by Cycles)


def test_bad_patterns_name_the_expected_shape(rig):
    mesh, _, _ = _plane(rig, [0.0, 0.0, -1.0])
    with pytest.raises(ValueError, match=r"patterns must have shape \(N, 1140, 912\)"):
        render(rig, [mesh], np.zeros((2, 100, 100), np.float32))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        render(rig, [mesh], np.full((1, 1140, 912), 2.0, np.float32))
    with pytest.raises(ValueError, match="SceneMesh"):
        render(rig, ["plane"], np.zeros((1, 1140, 912), np.float32))


def test_missing_environment_says_how_to_create_it(tmp_path, rig):
    with pytest.raises(BlenderNotInstalledError, match="dptpu sim setup-blender"):
        blender_python(tmp_path / "nothing-here")
    mesh, _, _ = _plane(rig, [0.0, 0.0, -1.0])
    with pytest.raises(BlenderNotInstalledError, match="dptpu sim setup-blender"):
        render(rig, [mesh], np.zeros((1, 1140, 912), np.float32), env_dir=tmp_path / "nothing-here")


def test_render_capture_with_the_blender_engine_decodes_to_its_ground_truth(blender_env, tmp_path):
    """``dptpu.sim.render.render_capture(..., engine='blender')``: the capture folder T1's CLI writes."""
    from dptpu.fpp.capture import load_sequence_images, read_capture
    from dptpu.sim.image_formation import parse_sequences
    from dptpu.sim.render import render_capture
    from dptpu.sim.scenes import load_scene

    rig = nominal_rig(camera_size=(80, 60))
    folder = render_capture(rig, load_scene("plane", rig), parse_sequences("16x4"), tmp_path / "capture",
                            engine="blender", blender_samples=16)
    capture = read_capture(folder)
    truth = np.load(folder / "gt.npz")
    frames = load_sequence_images(capture, capture.sequences[0]).astype(np.float64)
    assert frames.shape == (4, 60, 80) and frames.max() > 128  # 8-bit frames of a lit plane
    measured = wrapped_phase(frames).phase
    expected = 2 * np.pi * 16 * truth["projector_x"] / rig.projector.size[0]
    error_px = np.angle(np.exp(1j * (measured - expected))) * rig.projector.size[0] / (2 * np.pi * 16)
    assert np.median(np.abs(error_px[truth["valid"]])) < 0.2  # projector px; 80x60, 16 samples (measured 0.043)
