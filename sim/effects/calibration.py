"""Geometry-stage effect ``calibration_error``: the rig the frames were taken with is not the calibration written
with them.

The rendered (true) rig differs from the given one by:

- ``rotation_deg`` (3,): a rotation vector (Rodrigues, degrees) turning the projector about its own centre, in
  its own frame: ``X_p' = dR X_p + t`` with ``X_p = R_p X + T_p``;
- ``translation`` (3,): ``t`` above, rig units (the projector moved along its own axes);
- ``camera_focal_scale``, ``projector_focal_scale``: ``fx`` and ``fy`` (and the skew) multiplied;
- ``camera_principal_px`` (2,), ``projector_principal_px`` (2,): added to ``(cx, cy)``, pixels.

The world frame stays the camera's: a camera-projector error is carried by the projector's pose (a camera-side
pose error is the same error seen from the other end). The capture's calibration keeps the given rig, so a
reconstruction with it bends and scales what it measures (a sphere's radius and RMS change).
"""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig

__all__ = ["miscalibrated_rig", "CALIBRATION_PARAMETERS", "calibration_vector", "calibration_params"]

#: The effect's parameters flattened to a vector of 12, in this order (see :func:`calibration_vector`).
CALIBRATION_PARAMETERS = ("rotation_deg", "translation", "camera_focal_scale", "projector_focal_scale",
                          "camera_principal_px", "projector_principal_px")
_SIZES = {"rotation_deg": 3, "translation": 3, "camera_focal_scale": 1, "projector_focal_scale": 1,
          "camera_principal_px": 2, "projector_principal_px": 2}
_NEUTRAL = {"camera_focal_scale": 1.0, "projector_focal_scale": 1.0}


def calibration_vector(params: dict) -> np.ndarray:
    """The 12 numbers of a ``calibration_error`` parameter dict (focal scales as ``scale - 1``)."""
    out = []
    for name in CALIBRATION_PARAMETERS:
        value = np.atleast_1d(np.asarray(params.get(name, _NEUTRAL.get(name, [0.0] * _SIZES[name])), float))
        out.append(value - _NEUTRAL.get(name, 0.0))
    return np.concatenate(out)


def calibration_params(vector) -> dict:
    """Inverse of :func:`calibration_vector`: a parameter dict of plain floats and lists."""
    vector = np.asarray(vector, dtype=np.float64)
    if vector.shape != (12,):
        raise ValueError(f"a calibration_error vector has 12 numbers; got shape {vector.shape}")
    out, i = {}, 0
    for name in CALIBRATION_PARAMETERS:
        size = _SIZES[name]
        part = vector[i:i + size] + _NEUTRAL.get(name, 0.0)
        out[name] = float(part[0]) if size == 1 else [float(v) for v in part]
        i += size
    return out


def _scaled(device: DeviceModel, scale: float, principal) -> DeviceModel:
    K = device.K.copy()
    K[:2, :2] *= scale
    K[:2, 2] += np.asarray(principal, dtype=np.float64)
    return DeviceModel(K=K, dist=device.dist, R=device.R, T=device.T, size=device.size)


def miscalibrated_rig(rig: Rig, params: dict) -> Rig:
    """The rig the frames were taken with: ``rig`` (the calibration) changed by the ``calibration_error``
    parameters ``params`` (module docstring; missing keys are neutral)."""
    v = calibration_vector(params)
    dR = cv2.Rodrigues(np.radians(v[0:3]).reshape(3, 1))[0]
    projector = rig.projector
    projector = DeviceModel(K=projector.K, dist=projector.dist, R=dR @ projector.R, T=dR @ projector.T + v[3:6],
                            size=projector.size)
    camera = rig.camera if not np.any(v[[6, 8, 9]]) else _scaled(rig.camera, 1.0 + v[6], v[8:10])
    projector = _scaled(projector, 1.0 + v[7], v[10:12])
    return replace(rig, camera=camera, projector=projector)
