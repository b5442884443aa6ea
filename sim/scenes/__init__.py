"""Scenes of the digital twin: YAML scene files, built-in scenes, calibration boards, random scenes.

A :class:`Scene` is a list of :class:`~dptpu.sim.scene_mesh.SceneMesh` in the rig's world frame; every
renderer (``dptpu.sim.raycast``, ``dptpu.sim.blender``) draws exactly that list.
"""
from __future__ import annotations

from pathlib import Path

from dptpu.fpp.calibration import Rig

from .board import board_corners, board_scene
from .builtin import BUILTIN_SCENES, STANDARD_SPHERE_DIAMETER_MM, plane_scene, sphere_scene
from .random_scene import random_scene
from .scene import Scene, euler_xyz_deg, posed_mesh
from .scene_file import load_scene_file, parse_scene

__all__ = ["Scene", "load_scene", "random_scene", "board_scene", "board_corners", "sphere_scene", "plane_scene",
           "parse_scene", "BUILTIN_SCENES", "STANDARD_SPHERE_DIAMETER_MM", "euler_xyz_deg", "posed_mesh"]


def load_scene(path_or_name, rig: Rig) -> Scene:
    """A scene from a YAML scene file or a built-in name (``sphere``, ``plane``, ``board``).

    Raises
    ------
    FileNotFoundError
        Neither a built-in name nor an existing file.
    ValueError
        The scene file is invalid (the message names the file, the key and the expected value).
    """
    text = str(path_or_name)
    if text in BUILTIN_SCENES:
        return BUILTIN_SCENES[text](rig)
    path = Path(text)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such scene file (built-in scenes: {', '.join(BUILTIN_SCENES)})")
    return load_scene_file(path, rig)
