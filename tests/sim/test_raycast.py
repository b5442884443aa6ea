import cv2
import numpy as np
import pytest

from dptpu.sim.raycast import trace
from dptpu.sim.scene_mesh import SceneMesh
from dptpu.sim.scenes import load_scene, primitives
from dptpu.sim.scenes.scene import posed_mesh


def _cv_project(device, points):
    rvec, _ = cv2.Rodrigues(device.R)
    K = device.K.copy()
    projected, _ = cv2.projectPoints(points.reshape(-1, 1, 3), rvec, device.T, K, device.dist)
    return projected.reshape(-1, 2)


def test_plane_depth_points_and_projector_coordinates_are_exact(small_rig, plane_samples):
    s = plane_samples
    assert s.hit.all() and s.lit.all()
    np.testing.assert_allclose(s.depth, 800.0, atol=1e-9)
    np.testing.assert_allclose(s.points[..., 2], 800.0, atol=1e-9)  # camera frame = world frame
    np.testing.assert_allclose(s.normals, np.broadcast_to([0.0, 0.0, -1.0], s.normals.shape), atol=1e-12)
    # camera pixels: the hit points reproject (OpenCV, with distortion) onto the pixel centres
    v, u = np.mgrid[0:120, 0:160]
    reprojected = _cv_project(small_rig.camera, s.points.reshape(-1, 3))
    np.testing.assert_allclose(reprojected, np.stack([u.ravel(), v.ravel()], 1), atol=1e-6)
    # projector coordinates: OpenCV's projection of the same points, with the projector's distortion
    np.testing.assert_allclose(s.projector_xy.reshape(-1, 2), _cv_project(small_rig.projector, s.points.reshape(-1, 3)),
                               atol=1e-6)


def test_convention_projector_x_increases_with_camera_column(plane_samples):
    assert np.all(np.diff(plane_samples.projector_xy[..., 0], axis=1) > 0)


def test_sphere_points_lie_on_the_sphere_within_the_facet_sagitta(small_rig, sphere_samples):
    from dptpu.sim.rig import working_point

    centre, radius = working_point(small_rig), 50.8082 / 2
    distance = np.linalg.norm(sphere_samples.points[sphere_samples.hit] - centre, axis=1)
    sagitta = 7.24e-3  # deepest facet of the 5-subdivision icosphere of this radius (primitives.sphere)
    assert np.all(distance <= radius + 1e-9) and np.all(distance >= radius - sagitta)
    normals = sphere_samples.normals[sphere_samples.hit]
    radial = (sphere_samples.points[sphere_samples.hit] - centre) / distance[:, None]
    assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", normals, radial), -1, 1))).max() < 0.5


def test_shadow_rays_match_the_analytic_shadow_of_a_box(small_rig):
    plane = load_scene("plane", small_rig).meshes[0]
    vertices, triangles = primitives.box((20.0, 20.0, 20.0))
    box = posed_mesh("box", vertices, triangles, translation=[0.0, 0.0, 700.0])
    samples = trace(small_rig, [plane, box])
    on_plane = samples.mesh_index == 0
    # slab test: does the segment from a plane point to the projector centre cross the box?
    points = samples.points[on_plane]
    direction = small_rig.projector.center - points
    low, high = np.array([-10.0, -10.0, 690.0]), np.array([10.0, 10.0, 710.0])
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (low - points) / direction, (high - points) / direction
    t_near = np.nanmax(np.minimum(t1, t2), axis=1)
    t_far = np.nanmin(np.maximum(t1, t2), axis=1)
    shadowed = (t_near <= t_far) & (t_far > 0) & (t_near < 1)
    assert shadowed.sum() > 50  # the box casts a real shadow on the plane
    # pixels whose segment grazes the box edge may go either way: exclude a thin margin
    margin = np.abs(t_near - t_far) > 1e-3
    np.testing.assert_array_equal(samples.lit[on_plane][margin], ~shadowed[margin])
    assert samples.lit[samples.mesh_index == 1].sum() > 0


def test_texture_is_looked_up_with_barycentric_uv(small_rig):
    vertices, triangles, uv = primitives.plane((400.0, 300.0), 1)
    texture = np.tile(np.linspace(0.0, 1.0, 256, dtype=np.float32), (4, 1))  # albedo grows with u
    mesh = SceneMesh("ramp", vertices + [0.0, 0.0, 800.0], triangles, albedo_texture=texture, uv=uv)
    samples = trace(small_rig, [mesh])
    u_expected = (samples.points[..., 0] + 200.0) / 400.0
    texel = np.clip(u_expected * 256 - 0.5, 0, 255) / 255
    np.testing.assert_allclose(samples.albedo, 0.8 * texel, atol=1e-5)


def test_trace_needs_meshes(small_rig):
    with pytest.raises(ValueError, match="at least one mesh"):
        trace(small_rig, [])
