"""Point clouds written to a file (PLY; open3d picks the format from the suffix): the one writer of the package.

Every point-cloud file of the package is in metres (ROS's unit, REP 103), whatever the unit of the points: the
caller states the unit of the points it passes (``unit``: the rig's, e.g. mm for ``dptpu triangulate``, metres for
the cloud node's and the scan monitor's snapshots) and the file's unit (``file_unit``, metres unless a user asked
for millimetres), since PLY has no unit field.

Besides the coordinates a file may carry the cloud's other per-point values: ``normals`` (PLY ``nx ny nz``, PCD
``normal_x normal_y normal_z``, as PCL and MeshLab read them) and named float fields (``intensity``,
``modulation``, ``confidence``: the scanner's PointCloud2 fields, written under their names).
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .rig_model import METRES_PER_UNIT

__all__ = ["FIELD_SUFFIXES", "write_point_cloud"]

#: The formats that take normals and named fields (open3d's tensor point cloud writes them).
FIELD_SUFFIXES = (".ply", ".pcd")
#: Names a field may not take: open3d's own attributes and the coordinates.
_RESERVED = frozenset({"positions", "normals", "colors", "x", "y", "z", "nx", "ny", "nz", "normal_x", "normal_y",
                       "normal_z", "red", "green", "blue", "rgb"})


def write_point_cloud(path, points: np.ndarray, *, unit: str, file_unit: str = "m",
                      intensity: np.ndarray | None = None, normals: np.ndarray | None = None,
                      fields: Mapping[str, np.ndarray] | None = None) -> int:
    """Write the finite points of ``points`` to ``path`` through open3d (binary PLY for ``.ply``); returns their count.

    Parameters
    ----------
    path : str or Path
        The file; its suffix picks the format (``.ply``, ``.pcd``, ``.xyz``, ...).
    points : ndarray (..., 3)
        x, y, z in ``unit``, any leading shape (an organized (H, W, 3) cloud or (M, 3)); points with a NaN or inf
        coordinate are left out.
    unit : {"m", "cm", "mm", "um"}
        The unit of ``points`` (one of :data:`dptpu.fpp.rig_model.METRES_PER_UNIT`).
    file_unit : {"m", "cm", "mm", "um"}, default "m"
        The unit written: the points are scaled from ``unit`` to it.
    intensity : ndarray (...), optional
        Per point (the leading shape of ``points``): written as grey colours, scaled to its 99th percentile over
        the points kept. None: no colours.
    normals : ndarray (..., 3), optional
        Unit surface normals per point (no unit: not scaled), written as float64 like the coordinates (open3d's
        PCD writer gives both one size); PLY and PCD only.
    fields : mapping of str to ndarray (...), optional
        Further values per point, written as float32 properties under their names (e.g. ``{"intensity": ...,
        "confidence": ...}``; not scaled); PLY and PCD only.

    Returns
    -------
    int
        The number of points written.

    Raises
    ------
    ValueError
        An unknown unit, shapes that do not fit, a field name that is taken, normals or fields for another format
        than PLY or PCD, or a file open3d could not write (an unknown suffix, a folder that does not exist).
    """
    for name, value in (("unit", unit), ("file_unit", file_unit)):
        if value not in METRES_PER_UNIT:
            raise ValueError(f"{name} must be one of {', '.join(METRES_PER_UNIT)}; got {value!r}")
    points = np.asarray(points)
    if points.ndim < 2 or points.shape[-1] != 3:
        raise ValueError(f"points must have shape (..., 3); got {points.shape}")
    if intensity is not None and np.shape(intensity) != points.shape[:-1]:
        raise ValueError(f"intensity must have the shape {points.shape[:-1]} of the points; got {np.shape(intensity)}")
    fields = dict(fields or {})
    _check_fields(path, points.shape[:-1], normals, fields)
    import open3d as o3d  # a heavy import, needed only when a cloud is written

    finite = np.isfinite(points).all(axis=-1)  # (...)
    scale = METRES_PER_UNIT[unit] / METRES_PER_UNIT[file_unit]
    kept = np.ascontiguousarray(np.asarray(points[finite], dtype=np.float64) * scale)  # (M, 3) in file_unit
    grey = None
    if intensity is not None:
        grey = np.nan_to_num(np.asarray(intensity)[finite].astype(np.float64))
        scale = np.percentile(grey, 99) if grey.size else 1.0
        grey = np.clip(grey / (scale if scale > 0 else 1.0), 0.0, 1.0)  # (M,) 0..1
    if normals is None and not fields:
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(kept))
        if grey is not None:
            cloud.colors = o3d.utility.Vector3dVector(np.repeat(grey[:, None], 3, axis=1))
        written = o3d.io.write_point_cloud(Path(path), cloud, write_ascii=False)
    else:  # the tensor point cloud: named attributes become properties of their own
        def tensor(array, dtype):
            return o3d.core.Tensor.from_numpy(np.ascontiguousarray(array, dtype))

        tensors = o3d.t.geometry.PointCloud()
        tensors.point.positions = tensor(kept, np.float64)
        if grey is not None:  # as the legacy writer: 8-bit colours
            tensors.point.colors = tensor(np.repeat(np.round(grey * 255)[:, None], 3, axis=1), np.uint8)
        if normals is not None:  # float64 as the coordinates: open3d's PCD writer sizes both alike
            tensors.point.normals = tensor(np.asarray(normals)[finite], np.float64)
        for name, values in fields.items():
            tensors.point[name] = tensor(np.asarray(values)[finite][:, None], np.float32)
        written = o3d.t.io.write_point_cloud(Path(path), tensors, write_ascii=False)
    if not written:
        raise ValueError(f"{path}: open3d could not write the point cloud (is the suffix .ply/.pcd/.xyz, and does "
                         "the folder exist?)")
    return int(np.count_nonzero(finite))


def _check_fields(path, shape: tuple, normals, fields: dict) -> None:
    """ValueError unless ``normals`` (shape + (3,)) and ``fields`` (shape each, free names) fit ``path``."""
    if normals is None and not fields:
        return
    if Path(path).suffix.lower() not in FIELD_SUFFIXES:
        raise ValueError(f"{path}: normals and fields are written to {' and '.join(FIELD_SUFFIXES)} files only")
    if normals is not None and np.shape(normals) != (*shape, 3):
        raise ValueError(f"normals must have the shape {(*shape, 3)}; got {np.shape(normals)}")
    for name, values in fields.items():
        if not isinstance(name, str) or not name.isidentifier() or name in _RESERVED:
            raise ValueError(f"field name {name!r} must be an identifier other than {', '.join(sorted(_RESERVED))}")
        if np.shape(values) != shape:
            raise ValueError(f"field {name} must have the shape {shape} of the points; got {np.shape(values)}")
