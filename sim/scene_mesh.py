"""What every renderer of the twin consumes: triangle meshes in the rig's world frame, each with a material.

Scene files (``dptpu.sim.scenes``) turn into a list of :class:`SceneMesh`; the raycast renderer
(``dptpu.sim.raycast``) and the Blender worker (``dptpu.sim.blender``) both render exactly that list, so
the two engines see the same geometry and the same materials.

Convention: vertices are in the rig's world frame and units (``Rig.units``, mm for the DP-TPU rig);
triangles are counter-clockwise seen from outside, so normals ``(v1 - v0) x (v2 - v0)`` point out.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Material", "SceneMesh"]


@dataclass(frozen=True)
class Material:
    """A surface's reflectance, in the terms of Blender's Principled BSDF.

    Attributes
    ----------
    albedo : float
        Diffuse reflectance (base colour, grey), in [0, 1].
    roughness : float
        Microfacet roughness in [0, 1]; 1 is fully diffuse.
    specular : float
        Weight of the specular lobe in [0, 1] (Principled BSDF "Specular IOR Level" x 2 in Blender 4).
    ior : float
        Index of refraction (>= 1), sets the Fresnel reflectance at normal incidence.
    """

    albedo: float = 0.8
    roughness: float = 0.8
    specular: float = 0.0
    ior: float = 1.5

    def __post_init__(self):
        for name, low, high in (("albedo", 0.0, 1.0), ("roughness", 0.0, 1.0), ("specular", 0.0, 1.0),
                                ("ior", 1.0, 10.0)):
            value = float(getattr(self, name))
            if not (low <= value <= high):
                raise ValueError(f"material {name} must be in [{low}, {high}]; got {value}")
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class SceneMesh:
    """One object of a scene: a triangle mesh with one material.

    Attributes
    ----------
    name : str
        The object's name in the scene file (used in errors and in Blender's outliner).
    vertices : ndarray (V, 3) float64
        Vertex positions in the rig's world frame and units.
    triangles : ndarray (T, 3) int32
        Vertex indices, counter-clockwise seen from outside.
    material : Material
    albedo_texture : ndarray (Ht, Wt) float32 or None
        Optional grey texture in [0, 1] (a calibration board's squares), mapped through ``uv``; the diffuse
        reflectance is ``material.albedo * texture`` (texel centres at ``(i + 0.5) / Wt``, bilinear).
    uv : ndarray (V, 2) float64 or None
        Texture coordinates in [0, 1] per vertex (u right, v down in the texture image), when textured.
    """

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    material: Material = field(default_factory=Material)
    albedo_texture: np.ndarray | None = None
    uv: np.ndarray | None = None

    def __post_init__(self):
        vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
        triangles = np.ascontiguousarray(self.triangles, dtype=np.int32)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) < 3:
            raise ValueError(f"mesh {self.name!r}: vertices must have shape (V, 3) with V >= 3; got {vertices.shape}")
        if not np.all(np.isfinite(vertices)):
            raise ValueError(f"mesh {self.name!r}: vertices must be finite")
        if triangles.ndim != 2 or triangles.shape[1] != 3 or len(triangles) == 0:
            raise ValueError(f"mesh {self.name!r}: triangles must have shape (T, 3) with T >= 1; got {triangles.shape}")
        if triangles.min() < 0 or triangles.max() >= len(vertices):
            raise ValueError(f"mesh {self.name!r}: triangle indices must be in [0, {len(vertices) - 1}]")
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "triangles", triangles)
        if (self.albedo_texture is None) != (self.uv is None):
            raise ValueError(f"mesh {self.name!r}: albedo_texture and uv must be given together")
        if self.uv is not None:
            uv = np.ascontiguousarray(self.uv, dtype=np.float64)
            if uv.shape != (len(vertices), 2):
                raise ValueError(f"mesh {self.name!r}: uv must have shape ({len(vertices)}, 2); got {uv.shape}")
            texture = np.ascontiguousarray(self.albedo_texture, dtype=np.float32)
            if texture.ndim != 2:
                raise ValueError(f"mesh {self.name!r}: albedo_texture must have shape (Ht, Wt); got {texture.shape}")
            object.__setattr__(self, "uv", uv)
            object.__setattr__(self, "albedo_texture", texture)
