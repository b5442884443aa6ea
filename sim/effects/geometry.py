"""Geometry-stage effects: where the light goes.

- ``lens_distortion``: coefficients (k1 k2 p1 p2 k3) added to the camera's and the projector's distortion in the
  render only; the capture's calibration keeps the rig's own, so the data hold distortion the calibration does
  not model (a triangulated plane bends; the error grows with the radius in the image).
- ``calibration_error``: the rig the frames were taken with differs from the calibration written with them
  (:mod:`dptpu.sim.effects.calibration`); applied before ``lens_distortion``.
- ``motion``: rigid motion between frames; frame ``g`` (0-based over the whole capture, sequences in order) sees
  the meshes rotated by ``g * angular_deg_per_frame`` (Euler x, y, z, degrees) about their common centroid and
  translated by ``g * velocity_per_frame`` (rig units). Ground truth is frame 0's.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.sim.scene_mesh import SceneMesh
from dptpu.sim.scenes.scene import euler_xyz_deg

from .calibration import miscalibrated_rig
from .registry import find_effect

__all__ = ["render_rig", "moved_meshes", "has_motion"]


def render_rig(rig: Rig, effects) -> Rig:
    """The rig the renderer traces: ``rig`` changed by ``calibration_error``, with the ``lens_distortion``
    effect's coefficients added."""
    error = find_effect(effects, "calibration_error")
    if error is not None:
        rig = miscalibrated_rig(rig, error.params)
    effect = find_effect(effects, "lens_distortion")
    if effect is None:
        return rig

    def add(device: DeviceModel, extra) -> DeviceModel:
        return DeviceModel(K=device.K, dist=device.dist + np.asarray(extra), R=device.R, T=device.T,
                           size=device.size)

    return replace(rig, camera=add(rig.camera, effect["camera"]), projector=add(rig.projector, effect["projector"]))


def has_motion(effects) -> bool:
    effect = find_effect(effects, "motion")
    return effect is not None and (any(effect["velocity_per_frame"]) or any(effect["angular_deg_per_frame"]))


def moved_meshes(meshes, effects, frame_index: int) -> tuple:
    """The meshes as frame ``frame_index`` sees them under the ``motion`` effect."""
    effect = find_effect(effects, "motion")
    if effect is None or frame_index == 0:
        return tuple(meshes)
    R = euler_xyz_deg(np.asarray(effect["angular_deg_per_frame"]) * frame_index)
    shift = np.asarray(effect["velocity_per_frame"]) * frame_index
    centroid = np.vstack([m.vertices for m in meshes]).mean(axis=0)
    return tuple(SceneMesh(name=m.name, vertices=(m.vertices - centroid) @ R.T + centroid + shift,
                           triangles=m.triangles, material=m.material, albedo_texture=m.albedo_texture, uv=m.uv)
                 for m in meshes)
