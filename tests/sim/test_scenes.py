import numpy as np
import pytest
import yaml

from dptpu.sim.raycast import trace
from dptpu.sim.rig import working_point
from dptpu.sim.scenes import (
    STANDARD_SPHERE_DIAMETER_MM,
    board_scene,
    load_scene,
    primitives,
    random_scene,
    sphere_scene,
)
from dptpu.sim.scenes.scene import euler_xyz_deg


def _volume(vertices, triangles):
    v0, v1, v2 = (vertices[triangles[:, i]] for i in range(3))
    return np.einsum("ij,ij->i", v0, np.cross(v1, v2)).sum() / 6.0


@pytest.mark.parametrize("name, mesh, volume, rtol", [
    ("sphere", primitives.sphere(2.0, 5), 4.0 / 3.0 * np.pi * 8.0, 2e-3),
    ("box", primitives.box((1.0, 2.0, 3.0)), 6.0, 1e-12),
    ("cylinder", primitives.cylinder(1.0, 2.0, 256), 2.0 * np.pi, 2e-3),
    ("torus", primitives.torus(3.0, 1.0, 256), 2.0 * np.pi ** 2 * 3.0, 2e-3),
    ("superquadric", primitives.superquadric((1.0, 1.0, 1.0), (1.0, 1.0), 256), 4.0 / 3.0 * np.pi, 2e-3),
    ("step_block", primitives.step_block(3.0, 1.0, [1.0, 2.0, 3.0]), 6.0, 1e-12),
])
def test_closed_primitives_have_outward_normals_and_their_analytic_volume(name, mesh, volume, rtol):
    vertices, triangles = mesh
    assert _volume(vertices, triangles) == pytest.approx(volume, rel=rtol)


def test_sphere_vertices_lie_on_the_sphere():
    vertices, _ = primitives.sphere(25.4, 4)
    np.testing.assert_allclose(np.linalg.norm(vertices, axis=1), 25.4, rtol=1e-12)


def test_builtin_sphere_is_standard_and_seen_by_camera_and_projector(small_rig):
    scene = sphere_scene(small_rig, subdivisions=4)
    np.testing.assert_allclose(scene.landmarks["sphere_center"], working_point(small_rig))
    assert 2 * scene.landmarks["sphere_radius"] == pytest.approx(STANDARD_SPHERE_DIAMETER_MM)
    samples = trace(small_rig, scene)
    # the sphere subtends ~2600/4 * 50.8 / 775 ~ 43 px across in the 160x120 image: ~1400 pixels
    assert 1000 < samples.hit.sum() < 1800
    assert samples.lit.sum() > 0.9 * samples.hit.sum()


def test_board_corners_are_where_the_camera_sees_the_squares_meet(small_rig):
    R = euler_xyz_deg([10.0, -15.0, 5.0])
    scene = board_scene(small_rig, R, [-60.0, -45.0, 820.0], cols=7, rows=5, square_mm=15.0)
    corners = scene.landmarks["board_corners"]
    assert corners.shape == (35, 3)
    np.testing.assert_allclose(corners[1] - corners[0], R[:, 0] * 15.0)
    np.testing.assert_allclose(corners[7] - corners[0], R[:, 1] * 15.0)
    samples = trace(small_rig, scene)
    # the four squares around an inner corner alternate dark and light: trace the corner's neighbours
    from dptpu.sim.scenes.board import BLACK_ALBEDO

    assert samples.albedo[samples.hit].min() == pytest.approx(0.9 * BLACK_ALBEDO, rel=1e-3)
    assert samples.albedo[samples.hit].max() == pytest.approx(0.9, rel=1e-3)


def _scene_file(tmp_path, document):
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


def test_scene_file_places_objects_in_the_working_frame(tmp_path, small_rig):
    path = _scene_file(tmp_path, {"objects": [
        {"name": "ball", "shape": "sphere", "radius": 10.0, "frame": "working",
         "pose": {"translation": [5.0, 0.0, 0.0]}, "material": {"albedo": 0.5, "roughness": 0.3}},
        {"name": "steps", "shape": "step_block", "width": 40, "depth": 20, "step_heights": [5, 10],
         "frame": "camera", "pose": {"translation": [0, 0, 900], "rotation_deg": [0, 0, 90]}, "scale": 2},
    ]})
    scene = load_scene(path, small_rig)
    assert [m.name for m in scene.meshes] == ["ball", "steps"]
    ball = scene.meshes[0]
    np.testing.assert_allclose(ball.vertices.mean(axis=0), working_point(small_rig) + [5.0, 0.0, 0.0], atol=1e-9)
    assert ball.material.albedo == 0.5 and ball.material.roughness == 0.3
    steps = scene.meshes[1]
    np.testing.assert_allclose(np.ptp(steps.vertices, axis=0), [40.0, 80.0, 20.0], atol=1e-9)  # rotated, scaled


@pytest.mark.parametrize("objects, message", [
    ([{"shape": "sphere"}], r"scene.yaml: objects\[0\].radius: missing; shape sphere needs radius"),
    ([{"shape": "cone", "radius": 1}], r"objects\[0\].shape: must be one of sphere, box"),
    ([{"shape": "sphere", "radius": 1, "colour": 2}], r"objects\[0\].colour: unknown key"),
    ([{"shape": "sphere", "radius": -1}], r"objects\[0\].radius: must be a number > 0; got -1"),
    ([{"shape": "box", "size": [1, 2]}], r"objects\[0\].size: must be a list of 3 numbers > 0"),
    ([{"shape": "sphere", "radius": 1, "material": {"albedo": 2}}],
     r"objects\[0\].material.albedo: material albedo must be in \[0.0, 1.0\]; got 2.0"),
    ([{"shape": "sphere", "radius": 1, "pose": {"rotation": [[1, 0], [0, 1]]}}],
     r"objects\[0\].pose.rotation: must be finite numbers of shape \(3, 3\)"),
    ([{"shape": "sphere", "radius": 1, "frame": "projector"}], r"objects\[0\].frame: must be one of world"),
    ([{"shape": "mesh", "file": "nothing.stl"}], r"objects\[0\]: .*nothing.stl: no such mesh file"),
])
def test_bad_scene_file_names_file_key_and_expected_value(tmp_path, small_rig, objects, message):
    with pytest.raises(ValueError, match=message):
        load_scene(_scene_file(tmp_path, {"objects": objects}), small_rig)


def test_unknown_scene_name_is_a_missing_file(small_rig):
    with pytest.raises(FileNotFoundError, match="built-in scenes: sphere, plane, board"):
        load_scene("spheer", small_rig)


def test_random_scene_is_seeded_and_visible(small_rig):
    a, b, c = random_scene(small_rig, 7), random_scene(small_rig, 7), random_scene(small_rig, 8)
    assert [m.name for m in a.meshes] == [m.name for m in b.meshes]
    for ma, mb in zip(a.meshes, b.meshes):
        np.testing.assert_array_equal(ma.vertices, mb.vertices)
        assert ma.material == mb.material
    assert [m.name for m in a.meshes] != [m.name for m in c.meshes] or not np.array_equal(
        a.meshes[0].vertices, c.meshes[0].vertices)
    objects = [m for m in a.meshes if m.name != "background"]
    assert 3 <= len(objects) <= 6
    samples = trace(small_rig, a)
    seen = {int(i) for i in np.unique(samples.mesh_index[samples.lit])}
    assert len(seen) >= 3  # several objects lit and seen


def test_random_scene_draws_user_meshes(tmp_path, small_rig):
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh.create_cone(radius=1.0, height=3.0)
    o3d.io.write_triangle_mesh(str(tmp_path / "cone.stl"), mesh.compute_triangle_normals())
    scene = random_scene(small_rig, 3, meshes_dir=tmp_path, mesh_fraction=1.0)
    names = [m.name for m in scene.meshes if m.name != "background"]
    assert names and all(name.endswith("-cone") for name in names)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no mesh files"):
        random_scene(small_rig, 3, meshes_dir=tmp_path / "empty")
