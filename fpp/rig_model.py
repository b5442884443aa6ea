"""The rig model: a camera and a projector (an inverse camera) in one world frame.

Each device has ``K`` (3x3 intrinsics, skew allowed), ``dist`` (Brown-Conrady k1 k2 p1 p2 k3, OpenCV order), ``R``,
``T`` (world to device: ``X_dev = R @ X_world + T``) and ``size`` (width, height) in pixels. Units of ``T`` are the
rig's declared ``units`` (:data:`METRES_PER_UNIT`). The files a rig is read from and written to:
:mod:`dptpu.fpp.calibration`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .phase_harmonics import ProjectorPhaseResponse

__all__ = ["METRES_PER_UNIT", "DeviceModel", "Rig", "checked_array"]

#: The length units of a rig (and of the point clouds written from it), in metres.
METRES_PER_UNIT = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6}


@dataclass(frozen=True)
class DeviceModel:
    """One pinhole device (camera, or projector as an inverse camera) with Brown-Conrady distortion.

    Attributes
    ----------
    K : ndarray (3, 3)
        Intrinsics ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, pixels.
    dist : ndarray (5,)
        ``k1, k2, p1, p2, k3`` (OpenCV order; Bouguet's ``kc`` is the same order).
    R : ndarray (3, 3)
        Rotation world -> device.
    T : ndarray (3,)
        Translation world -> device, in the rig's units.
    size : tuple of int
        ``(width, height)`` in pixels.

    Convention: pixel centres are 0-based, ``X_dev = R @ X_world + T``, ``x_pix = K @ distort(X_dev / z)``.
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    T: np.ndarray
    size: tuple[int, int]

    def __post_init__(self):
        K = checked_array(self.K, (3, 3), "K")
        if K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1 or K[1, 0] != 0:
            raise ValueError(f"K must be upper triangular with K[2] = [0, 0, 1]; got {K.tolist()}")
        dist = np.zeros(5)
        given = np.asarray(self.dist, dtype=np.float64).ravel()
        if given.size not in (4, 5) or not np.all(np.isfinite(given)):
            raise ValueError(f"dist must hold 4 or 5 finite coefficients (k1 k2 p1 p2 [k3]); got {given.tolist()}")
        dist[: given.size] = given
        R = checked_array(self.R, (3, 3), "R")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ValueError("R must be a rotation matrix (orthonormal, det +1)")
        T = checked_array(self.T, (3,), "T")
        size = tuple(int(v) for v in np.asarray(self.size).ravel())
        if len(size) != 2 or min(size) <= 0:
            raise ValueError(f"size must be (width, height) > 0; got {self.size}")
        for name, value in (("K", K), ("dist", dist), ("R", R), ("T", T), ("size", size)):
            object.__setattr__(self, name, value)

    @property
    def projection_matrix(self) -> np.ndarray:
        """``K [R | T]``, (3, 4): the paper's Eq. (10) without distortion."""
        return self.K @ np.hstack([self.R, self.T[:, None]])

    @property
    def center(self) -> np.ndarray:
        """Optical centre in world coordinates, ``-R^T T`` (the paper's Eq. (13)), shape (3,)."""
        return -self.R.T @ self.T


@dataclass(frozen=True)
class Rig:
    """A camera and a projector in one world frame, with the twin's physical effects (docs/effects.md) and the
    projector's calibrated phase response (``projector.phase_response`` of the rig file, docs/calibration.md; None:
    not calibrated, phases used as computed)."""

    camera: DeviceModel
    projector: DeviceModel
    units: str = "mm"
    effects: tuple = field(default_factory=tuple)
    phase_response: ProjectorPhaseResponse | None = None

    @property
    def scale_to_m(self) -> float:
        """Factor from the rig's units to metres."""
        try:
            return METRES_PER_UNIT[self.units]
        except KeyError:
            raise ValueError(f"rig units must be one of m, cm, mm, um; got {self.units!r}") from None


def checked_array(value, shape, name) -> np.ndarray:
    """``value`` as a finite float64 array of ``shape`` (a 3-vector may come in any 3-element shape); ValueError
    naming ``name`` otherwise."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numeric with shape {shape}; got {value!r}") from None
    if array.shape != shape:
        array = array.reshape(-1) if shape == (3,) and array.size == 3 else array
    if array.shape != shape:
        raise ValueError(f"{name} must have shape {shape}; got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or inf")
    return array
