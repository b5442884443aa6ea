import numpy as np
import pytest

from dptpu.fpp.phase import wrapped_phase
from dptpu.sim.image_formation import (
    DEFAULT_AMPLITUDE,
    DEFAULT_OFFSET,
    SequenceSpec,
    parse_sequences,
    reflectance_factor,
    render_frames,
    render_frames_float,
)
from dptpu.sim.raycast import trace
from dptpu.sim.rig import working_point
from dptpu.sim.scene_mesh import Material
from dptpu.sim.scenes import plane_scene

W = 912


def test_lambertian_plane_frames_follow_the_documented_formula(small_rig, plane_samples):
    s = plane_samples
    frames = render_frames_float(small_rig, s, [SequenceSpec(96, 4)])[0]
    to_projector = small_rig.projector.center - s.points
    distance = np.linalg.norm(to_projector, axis=-1)
    cos_i = np.einsum("...i,...i->...", s.normals, to_projector / distance[..., None])
    d_ref = np.linalg.norm(working_point(small_rig) - small_rig.projector.center)
    factor = s.albedo.astype(np.float64) * cos_i * (d_ref / distance) ** 2  # albedo 0.8 (float32)
    np.testing.assert_allclose(reflectance_factor(small_rig, s), factor, rtol=1e-12)
    theta = 2 * np.pi * 96 * s.projector_xy[..., 0] / W
    for n in range(4):
        expected = 255 * factor * (DEFAULT_OFFSET + DEFAULT_AMPLITUDE * np.cos(theta - 2 * np.pi * n / 4))
        np.testing.assert_allclose(frames[n], expected, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("axis, sign", [("x", -1), ("y", -1), ("x", 1)])
def test_convention_wrapped_phase_of_float_frames_is_the_projector_phase(small_rig, plane_samples, axis, sign):
    frames = render_frames_float(small_rig, plane_samples, [SequenceSpec(10.9, 5, axis=axis, shift_sign=sign)])[0]
    psi = wrapped_phase(frames, shift_sign=sign).phase
    coord = plane_samples.projector_xy[..., 0 if axis == "x" else 1]
    extent = 912 if axis == "x" else 1140
    expected = np.mod(2 * np.pi * 10.9 * coord / extent, 2 * np.pi)
    error = np.angle(np.exp(1j * (psi - expected)))
    assert np.abs(error).max() < 1e-9


def test_white_and_black_frames_and_quantization(small_rig, plane_samples):
    white, black = render_frames(small_rig, plane_samples, parse_sequences("white,black"), bit_depth=16)
    assert white.dtype == np.uint16 and white.shape == (1, 120, 160)
    expected = np.rint(65535 * reflectance_factor(small_rig, plane_samples))
    np.testing.assert_array_equal(white[0], expected.astype(np.uint16))
    assert black.max() == 0


def test_specular_lobe_adds_light_around_the_mirror_direction(small_rig):
    matte = trace(small_rig, plane_scene(small_rig, material=Material(albedo=0.5, roughness=0.3, specular=0.0)))
    shiny = trace(small_rig, plane_scene(small_rig, material=Material(albedo=0.5, roughness=0.3, specular=1.0)))
    extra = reflectance_factor(small_rig, shiny) - reflectance_factor(small_rig, matte)
    assert extra.min() > 0
    # the highlight sits where the half vector meets the normal: between camera and projector on the plane
    v, u = np.unravel_index(np.argmax(extra), extra.shape)
    point = shiny.points[v, u]
    to_c = small_rig.camera.center - point
    to_p = small_rig.projector.center - point
    half = to_c / np.linalg.norm(to_c) + to_p / np.linalg.norm(to_p)
    half /= np.linalg.norm(half)
    assert np.degrees(np.arccos(half @ np.array([0.0, 0.0, -1.0]))) < 0.5


def test_parse_sequences():
    sequences = parse_sequences("96x12,1x12,64x3:y,white")
    assert [s.label for s in sequences] == ["96x12", "1x12", "64x3", "white"]
    assert sequences[2].axis == "y"
    with pytest.raises(ValueError, match="expected FREQxSTEPS"):
        parse_sequences("96")
    with pytest.raises(ValueError, match="steps must be an integer >= 3"):
        parse_sequences("96x2")


def test_shadowed_and_background_pixels_are_black(small_rig):
    from dptpu.sim.scenes import sphere_scene

    samples = trace(small_rig, sphere_scene(small_rig, subdivisions=3))
    frames = render_frames(small_rig, samples, [SequenceSpec(16, 3)])[0]
    assert frames[:, ~samples.hit].max() == 0
    assert frames[:, samples.lit].max() > 100
