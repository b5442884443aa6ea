"""What Blender's camera cannot do (skew, ``fx != fy``, lens distortion), done by resampling its render.

Blender renders an ideal pinhole with square pixels and no skew: ``K_r = [[f, 0, cx_r], [0, f, cy_r], [0, 0, 1]]``
at ``size_r``. Every pixel ``(u, v)`` of the real camera looks along the undistorted normalized direction
``(x, y) = undistort(K^-1 (u, v))``, which the ideal render shows at ``(f x + cx_r, f y + cy_r)``; the real frame
is the render sampled there (cubic B-spline interpolation: bilinear interpolation biases the phase of fringes a
few pixels wide by ~0.05 projector pixels where the two grids keep a constant sub-pixel offset; the cubic spline
brings that under 0.005). When the real camera is itself such a pinhole (to ``tolerance_px``), the render is the
frame and nothing is resampled.

Convention: 0-based pixel centres (docs/architecture.md); ``f = max(fx, fy)`` so the render never undersamples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import map_coordinates

from dptpu.fpp.calibration import DeviceModel
from dptpu.fpp.distortion import pixels_to_normalized, undistort

__all__ = ["RenderCamera", "render_camera", "source_pixels", "warp_to_device"]

#: Pixels kept around the real image's footprint in the render, for the interpolation's neighbours.
_MARGIN_PX = 2.0
#: A render larger than this many times the real image (in pixels) means a distortion model gone wild.
_MAX_AREA_RATIO = 4.0


@dataclass(frozen=True)
class RenderCamera:
    """The ideal pinhole Blender renders for one real camera.

    Attributes
    ----------
    K : ndarray (3, 3)
        ``[[f, 0, cx], [0, f, cy], [0, 0, 1]]``, pixels.
    size : (int, int)
        ``(width, height)`` of the render.
    warp : bool
        True when the render must be resampled into the real camera (:func:`warp_to_device`).
    """

    K: np.ndarray
    size: tuple[int, int]
    warp: bool

    def device(self, like: DeviceModel) -> DeviceModel:
        """The render camera as a :class:`DeviceModel` with the pose of ``like`` and no distortion."""
        return DeviceModel(K=self.K, dist=np.zeros(5), R=like.R, T=like.T, size=self.size)


def source_pixels(device: DeviceModel, K_render: np.ndarray) -> np.ndarray:
    """Where each real camera pixel lies in an ideal render with intrinsics ``K_render``, (H, W, 2) as (u, v)."""
    width, height = device.size
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    xy = undistort(pixels_to_normalized(np.stack([u, v], axis=-1), device.K), device.dist)  # (H, W, 2)
    return np.stack([K_render[0, 0] * xy[..., 0] + K_render[0, 2], K_render[1, 1] * xy[..., 1] + K_render[1, 2]],
                    axis=-1)


def render_camera(device: DeviceModel, *, tolerance_px: float = 1e-3) -> RenderCamera:
    """The ideal pinhole to render for ``device`` (see the module docstring).

    Parameters
    ----------
    device : DeviceModel
        The real camera.
    tolerance_px : float
        Largest displacement, in pixels, for which the device counts as an ideal pinhole (no resampling).

    Returns
    -------
    RenderCamera
    """
    fx, fy = float(device.K[0, 0]), float(device.K[1, 1])
    cx, cy = float(device.K[0, 2]), float(device.K[1, 2])
    direct = np.array([[fx, 0.0, cx], [0.0, fx, cy], [0.0, 0.0, 1.0]])
    width, height = device.size
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    offset = source_pixels(device, direct) - np.stack([u, v], axis=-1)  # (H, W, 2)
    if float(np.max(np.abs(offset))) <= tolerance_px:
        return RenderCamera(K=direct, size=(int(width), int(height)), warp=False)
    f = max(fx, fy)
    ideal = source_pixels(device, np.array([[f, 0.0, 0.0], [0.0, f, 0.0], [0.0, 0.0, 1.0]]))  # (H, W, 2), c = 0
    low = ideal.reshape(-1, 2).min(axis=0) - _MARGIN_PX - 0.5
    high = ideal.reshape(-1, 2).max(axis=0) + _MARGIN_PX + 0.5
    size = np.ceil(high - low).astype(int)
    if size[0] * size[1] > _MAX_AREA_RATIO * width * height:
        raise ValueError(f"camera distortion {device.dist.tolist()} spreads the {width}x{height} image over a "
                         f"{size[0]}x{size[1]} ideal render; the distortion model is not usable for rendering")
    K = np.array([[f, 0.0, -low[0] - 0.5], [0.0, f, -low[1] - 0.5], [0.0, 0.0, 1.0]])
    return RenderCamera(K=K, size=(int(size[0]), int(size[1])), warp=True)


def warp_to_device(frames: np.ndarray, render: RenderCamera, device: DeviceModel) -> np.ndarray:
    """Resample ideal renders into the real camera.

    Parameters
    ----------
    frames : ndarray (N, H_r, W_r)
        Renders of :func:`render_camera`'s pinhole.
    render : RenderCamera
    device : DeviceModel
        The real camera.

    Returns
    -------
    ndarray (N, H, W) float32
        The frames as the real camera sees them (cubic B-spline, clipped at 0; unchanged when ``render.warp`` is
        False).
    """
    frames = np.asarray(frames, dtype=np.float32)
    expected = (render.size[1], render.size[0])
    if frames.ndim != 3 or frames.shape[1:] != expected:
        raise ValueError(f"frames must have shape (N, {expected[0]}, {expected[1]}); got {frames.shape}")
    if not render.warp:
        return frames
    where = source_pixels(device, render.K)  # (H, W, 2)
    coordinates = np.stack([where[..., 1], where[..., 0]])  # (2, H, W): rows, columns
    warped = np.stack([map_coordinates(frame, coordinates, order=3, mode="nearest") for frame in frames])
    return np.maximum(warped, 0.0, out=warped)  # the spline may ring below 0 at a dark edge
