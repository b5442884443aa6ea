"""The resampling that gives Blender's ideal pinhole render the real camera's skew, aspect and distortion."""
import numpy as np
import pytest

from dptpu.fpp.calibration import DeviceModel
from dptpu.fpp.triangulate import camera_rays
from dptpu.sim.blender.camera_warp import render_camera, source_pixels, warp_to_device


def _camera(dist, K=((650.0, 0.3, 81.6), (0.0, 650.4, 57.1), (0.0, 0.0, 1.0))):
    a = np.radians(10.0)
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    return DeviceModel(K=np.array(K), dist=dist, R=R, T=[5.0, -3.0, 20.0], size=(160, 120))


def test_an_ideal_pinhole_is_rendered_as_it_is():
    camera = _camera(np.zeros(5), K=((650.0, 0.0, 81.6), (0.0, 650.0, 57.1), (0.0, 0.0, 1.0)))
    pinhole = render_camera(camera)
    assert not pinhole.warp and pinhole.size == (160, 120)
    np.testing.assert_array_equal(pinhole.K, camera.K)
    frames = np.random.default_rng(0).random((2, 120, 160)).astype(np.float32)
    np.testing.assert_array_equal(warp_to_device(frames, pinhole, camera), frames)


def test_source_pixels_are_the_render_cameras_projection_of_each_real_pixels_ray():
    camera = _camera([-0.13, -0.5, -0.0014, -0.0004, 0.0])
    pinhole = render_camera(camera)
    assert pinhole.warp and pinhole.K[0, 1] == 0 and pinhole.K[0, 0] == pinhole.K[1, 1] == 650.4
    rays = camera_rays(camera)  # (H, W, 3) world directions through the real camera's model
    local = rays @ camera.R.T  # directions in the camera frame (same pose for the render)
    projected = local @ pinhole.K.T
    expected = projected[..., :2] / projected[..., 2:]
    np.testing.assert_allclose(source_pixels(camera, pinhole.K), expected, atol=1e-9)
    where = source_pixels(camera, pinhole.K).reshape(-1, 2)
    assert where.min() >= 1.5 and (where < np.array(pinhole.size) - 2.5).all()  # inside, with a margin


def test_warp_samples_a_smooth_render_at_the_source_pixels():
    camera = _camera([-0.13, -0.5, -0.0014, -0.0004, 0.0])
    pinhole = render_camera(camera)
    rows, cols = np.mgrid[0:pinhole.size[1], 0:pinhole.size[0]].astype(float)

    def fringes(u, v):  # 0.5 + 0.4 cos(.), period ~6 render pixels, as a fringe image
        return 0.5 + 0.4 * np.cos(2 * np.pi * (u / 6.1 + v / 23.0))

    warped = warp_to_device(fringes(cols, rows)[None].astype(np.float32), pinhole, camera)[0]
    where = source_pixels(camera, pinhole.K)
    np.testing.assert_allclose(warped, fringes(where[..., 0], where[..., 1]), atol=0.01)


def test_warp_checks_the_frames_shape():
    camera = _camera([-0.1, 0, 0, 0, 0])
    pinhole = render_camera(camera)
    with pytest.raises(ValueError, match=r"frames must have shape \(N, "):
        warp_to_device(np.zeros((1, 120, 160)), pinhole, camera)
