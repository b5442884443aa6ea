"""Scene files: YAML lists of objects (a mesh file or a procedural shape) with pose, scale and material.

Format (``docs/twin.md`` has the full reference)::

    format: dptpu-scene/1          # optional
    name: steps-and-ball           # optional (default: the file stem)
    objects:
      - name: ball
        shape: sphere              # sphere box cylinder torus superquadric blob step_block plane mesh
        radius: 25.4               # the shape's parameters (below)
        frame: working             # world (default) | camera | working: what the pose is relative to
        pose: {translation: [0, 0, 0], rotation_deg: [0, 0, 0]}   # or rotation: 3x3 matrix
        scale: 1.0                 # or [sx, sy, sz]
        material: {albedo: 0.8, roughness: 0.6, specular: 0.1, ior: 1.5}
      - name: part
        shape: mesh
        file: meshes/part.stl      # relative to the scene file; read with open3d
        fit_size: 60               # optional: scale so the largest bounding-box edge is 60 (units)

Frames: ``world`` is the rig's world frame; ``camera`` the camera's optical frame (x right, y down, z forward);
``working`` has the camera's axes and its origin at the rig's working point (:func:`dptpu.sim.rig.working_point`),
so one scene file suits any rig.

Validation is strict: an unknown key, a missing required key or a value of the wrong type or range raises
``ValueError`` naming the file, the key path (``objects[1].material.albedo``) and what was expected.
"""
from __future__ import annotations

import numbers
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dptpu.fpp.calibration import Rig
from dptpu.fpp.text_files import read_text_file
from dptpu.sim.rig import working_point
from dptpu.sim.scene_mesh import Material

from . import primitives
from .scene import Scene, euler_xyz_deg, posed_mesh

__all__ = ["SCENE_FORMAT", "SHAPE_PARAMETERS", "load_scene_file", "parse_scene", "load_mesh_file"]

SCENE_FORMAT = "dptpu-scene/1"
_COMMON_KEYS = ("name", "shape", "frame", "pose", "scale", "material")
_FRAMES = ("world", "camera", "working")
#: shape -> {parameter: (kind, default or REQUIRED)}; kind: "pos" positive number, "num" number, "int" integer
#: >= 1, "vec2"/"vec3" positive 2/3-vectors, "list" list of positive numbers, "str" a string.
REQUIRED = object()
SHAPE_PARAMETERS = {
    "sphere": {"radius": ("pos", REQUIRED), "subdivisions": ("int", 5)},
    "box": {"size": ("vec3", REQUIRED)},
    "cylinder": {"radius": ("pos", REQUIRED), "height": ("pos", REQUIRED), "resolution": ("int", 64)},
    "torus": {"major_radius": ("pos", REQUIRED), "minor_radius": ("pos", REQUIRED), "resolution": ("int", 64)},
    "superquadric": {"radii": ("vec3", REQUIRED), "exponents": ("vec2", [0.5, 0.5]), "resolution": ("int", 64)},
    "blob": {"radius": ("pos", REQUIRED), "amplitude": ("num", 0.2), "seed": ("int0", 0), "subdivisions": ("int", 4)},
    "step_block": {"width": ("pos", REQUIRED), "depth": ("pos", REQUIRED), "step_heights": ("list", REQUIRED)},
    "plane": {"size": ("vec2", REQUIRED), "subdivisions": ("int", 1)},
    "mesh": {"file": ("str", REQUIRED), "fit_size": ("pos", None)},
}
_EXPECTED = {"pos": "a number > 0", "num": "a number", "int": "an integer >= 1", "int0": "an integer >= 0",
             "vec2": "a list of 2 numbers > 0", "vec3": "a list of 3 numbers > 0",
             "list": "a non-empty list of numbers > 0", "str": "a string"}


class _Where:
    """Error messages that name the file and the key path."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, message: str):
        raise ValueError(f"{self.source}: {key}: {message}")


def load_scene_file(path, rig: Rig) -> Scene:
    """Read and validate a scene YAML file into a :class:`Scene` placed in ``rig``'s world."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such scene file")
    text = read_text_file(path, "a scene YAML file (docs/twin.md)")
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({' '.join(str(exc).split())})") from None
    return parse_scene(document, rig, source=str(path), root=path.parent, default_name=path.stem)


def parse_scene(document, rig: Rig, *, source: str = "<scene>", root=None, default_name="scene") -> Scene:
    """A :class:`Scene` from a parsed scene document (see the module docstring)."""
    where = _Where(source)
    if not isinstance(document, dict):
        where.fail("(top level)", "a scene file must be a mapping with an 'objects' list")
    unknown = sorted(set(document) - {"format", "name", "objects"})
    if unknown:
        where.fail(unknown[0], "unknown key; expected one of format, name, objects")
    if "format" in document and document["format"] != SCENE_FORMAT:
        where.fail("format", f"must be '{SCENE_FORMAT}'; got {document['format']!r}")
    objects = document.get("objects")
    if not isinstance(objects, list) or not objects:
        where.fail("objects", f"must be a non-empty list of objects; got {objects!r}")
    root = Path(root) if root is not None else Path.cwd()
    meshes = [_parse_object(where, entry, f"objects[{i}]", rig, root) for i, entry in enumerate(objects)]
    names = [m.name for m in meshes]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        where.fail("objects", f"object names must be unique; {duplicates[0]!r} appears twice")
    name = document.get("name", default_name)
    if not isinstance(name, str):
        where.fail("name", f"must be a string; got {name!r}")
    return Scene(meshes=meshes, name=name, source=source)


def _parse_object(where: _Where, entry, key: str, rig: Rig, root: Path):
    if not isinstance(entry, dict):
        where.fail(key, f"must be a mapping with shape, pose, material; got {entry!r}")
    shape = entry.get("shape")
    if shape not in SHAPE_PARAMETERS:
        where.fail(f"{key}.shape", f"must be one of {', '.join(SHAPE_PARAMETERS)}; got {shape!r}")
    allowed = set(_COMMON_KEYS) | set(SHAPE_PARAMETERS[shape])
    unknown = sorted(set(entry) - allowed)
    if unknown:
        where.fail(f"{key}.{unknown[0]}",
                   f"unknown key for shape {shape}; expected one of {', '.join(sorted(allowed))}")
    name = entry.get("name", f"object{key[8:-1]}")
    if not isinstance(name, str) or not name:
        where.fail(f"{key}.name", f"must be a non-empty string; got {name!r}")
    params: dict[str, Any] = {}
    for param, (kind, default) in SHAPE_PARAMETERS[shape].items():
        if param not in entry:
            if default is REQUIRED:
                where.fail(f"{key}.{param}", f"missing; shape {shape} needs {param} ({_EXPECTED[kind]})")
            params[param] = default
        else:
            params[param] = _value(where, f"{key}.{param}", entry[param], kind)
    uv = texture = None
    try:
        if shape == "mesh":
            vertices, triangles = load_mesh_file(root / params["file"])
            if params["fit_size"] is not None:
                vertices = _fit(vertices, params["fit_size"])
        elif shape == "plane":
            vertices, triangles, uv = primitives.plane(params["size"], params["subdivisions"])
            uv = None
        else:
            vertices, triangles = primitives.SHAPES[shape](**params)
    except (ValueError, FileNotFoundError) as exc:
        where.fail(key, str(exc))
    frame = entry.get("frame", "world")
    if frame not in _FRAMES:
        where.fail(f"{key}.frame", f"must be one of {', '.join(_FRAMES)}; got {frame!r}")
    rotation, translation = _parse_pose(where, f"{key}.pose", entry.get("pose", {}))
    scale = _parse_scale(where, f"{key}.scale", entry.get("scale", 1.0))
    material = _parse_material(where, f"{key}.material", entry.get("material", {}))
    rotation, translation = _to_world(rig, frame, rotation, translation)
    return posed_mesh(name, vertices, triangles, rotation=rotation, translation=translation, scale=scale,
                      material=material, albedo_texture=texture, uv=uv)


def _to_world(rig: Rig, frame: str, rotation, translation):
    """Pose in ``frame`` -> pose in the rig's world frame."""
    if frame == "world":
        return rotation, translation
    R_cw = rig.camera.R.T  # camera axes in world
    origin = rig.camera.center if frame == "camera" else working_point(rig)
    return R_cw @ rotation, origin + R_cw @ translation


def _parse_pose(where, key, pose):
    if not isinstance(pose, dict):
        where.fail(key, f"must be a mapping with translation and rotation_deg or rotation; got {pose!r}")
    unknown = sorted(set(pose) - {"translation", "rotation_deg", "rotation"})
    if unknown:
        where.fail(f"{key}.{unknown[0]}", "unknown key; expected translation, rotation_deg or rotation")
    if "rotation_deg" in pose and "rotation" in pose:
        where.fail(key, "give rotation_deg (Euler x, y, z in degrees) or rotation (3x3 matrix), not both")
    translation = _numbers(where, f"{key}.translation", pose.get("translation", [0, 0, 0]), (3,))
    if "rotation" in pose:
        rotation = _numbers(where, f"{key}.rotation", pose["rotation"], (3, 3))
        if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or np.linalg.det(rotation) < 0:
            where.fail(f"{key}.rotation", "must be a rotation matrix (orthonormal, det +1)")
    else:
        rotation = euler_xyz_deg(_numbers(where, f"{key}.rotation_deg", pose.get("rotation_deg", [0, 0, 0]), (3,)))
    return rotation, translation


def _parse_scale(where, key, scale):
    if isinstance(scale, numbers.Real) and not isinstance(scale, bool):
        values = np.full(3, float(scale))
    else:
        values = _numbers(where, key, scale, (3,))
    if not np.all(np.isfinite(values)) or np.any(values == 0):
        where.fail(key, f"must be a non-zero number or 3 non-zero numbers; got {scale!r}")
    return values


def _parse_material(where, key, material):
    if not isinstance(material, dict):
        where.fail(key, f"must be a mapping with albedo, roughness, specular, ior; got {material!r}")
    fields = ("albedo", "roughness", "specular", "ior")
    unknown = sorted(set(material) - set(fields))
    if unknown:
        where.fail(f"{key}.{unknown[0]}", f"unknown key; expected one of {', '.join(fields)}")
    values = {}
    for name in fields:
        if name in material:
            value = material[name]
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                where.fail(f"{key}.{name}", f"must be a number; got {value!r}")
            values[name] = float(value)
    try:
        return Material(**values)
    except ValueError as exc:
        bad = str(exc).split()[1]
        where.fail(f"{key}.{bad}", str(exc))


def _numbers(where, key, value, shape):
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        where.fail(key, f"must be numbers of shape {shape}; got {value!r}")
    if array.shape != shape or not np.all(np.isfinite(array)):
        where.fail(key, f"must be finite numbers of shape {shape}; got {value!r}")
    return array


def _value(where, key, value, kind):
    if kind == "str":
        if not isinstance(value, str) or not value:
            where.fail(key, f"must be {_EXPECTED[kind]}; got {value!r}")
        return value
    if kind in ("int", "int0"):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < (1 if kind == "int" else 0):
            where.fail(key, f"must be {_EXPECTED[kind]}; got {value!r}")
        return int(value)
    if kind in ("pos", "num"):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) or (
                kind == "pos" and value <= 0):
            where.fail(key, f"must be {_EXPECTED[kind]}; got {value!r}")
        return float(value)
    expected_len = {"vec2": 2, "vec3": 3}.get(kind)
    if not isinstance(value, (list, tuple)) or (expected_len and len(value) != expected_len) or not value:
        where.fail(key, f"must be {_EXPECTED[kind]}; got {value!r}")
    for item in value:
        if isinstance(item, bool) or not isinstance(item, numbers.Real) or not np.isfinite(item) or item <= 0:
            where.fail(key, f"must be {_EXPECTED[kind]}; got {value!r}")
    return [float(v) for v in value]


def _fit(vertices, size):
    """Centre on the bounding box and scale so its largest edge is ``size``."""
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    extent = float((high - low).max())
    if extent <= 0:
        raise ValueError("mesh has zero extent")
    return (vertices - (low + high) / 2.0) * (size / extent)


def load_mesh_file(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) float64 and triangles (T, 3) int32 of a mesh file (STL, OBJ, PLY, OFF, ... via open3d)."""
    import open3d as o3d  # heavy: loaded on first use

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such mesh file")
    mesh = o3d.io.read_triangle_mesh(path)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    triangles = np.asarray(mesh.triangles, dtype=np.int32)
    if len(vertices) < 3 or len(triangles) == 0:
        raise ValueError(f"{path}: open3d read no triangles (an empty or unsupported mesh file)")
    return vertices, triangles
