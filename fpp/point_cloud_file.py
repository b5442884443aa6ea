"""Point clouds written to a file (PLY; open3d picks the format from the suffix): the one writer of the package.

Every point-cloud file of the package is in metres (ROS's unit, REP 103), whatever the unit of the points: the
caller states the unit of the points it passes (``unit``: the rig's, e.g. mm for ``dptpu triangulate``, metres for
the cloud node's and the scan monitor's snapshots) and the file's unit (``file_unit``, metres unless a user asked
for millimetres), since PLY has no unit field.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .rig_model import METRES_PER_UNIT

__all__ = ["write_point_cloud"]


def write_point_cloud(path, points: np.ndarray, *, unit: str, file_unit: str = "m",
                      intensity: np.ndarray | None = None) -> int:
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

    Returns
    -------
    int
        The number of points written.

    Raises
    ------
    ValueError
        An unknown unit, shapes that do not fit, or a file open3d could not write (an unknown
        suffix, a folder that does not exist).
    """
    for name, value in (("unit", unit), ("file_unit", file_unit)):
        if value not in METRES_PER_UNIT:
            raise ValueError(f"{name} must be one of {', '.join(METRES_PER_UNIT)}; got {value!r}")
    points = np.asarray(points)
    if points.ndim < 2 or points.shape[-1] != 3:
        raise ValueError(f"points must have shape (..., 3); got {points.shape}")
    if intensity is not None and np.shape(intensity) != points.shape[:-1]:
        raise ValueError(f"intensity must have the shape {points.shape[:-1]} of the points; got {np.shape(intensity)}")
    import open3d as o3d  # a heavy import, needed only when a cloud is written

    finite = np.isfinite(points).all(axis=-1)  # (...)
    scale = METRES_PER_UNIT[unit] / METRES_PER_UNIT[file_unit]
    kept = np.asarray(points[finite], dtype=np.float64) * scale  # (M, 3) in file_unit
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(kept)))
    if intensity is not None:
        grey = np.nan_to_num(np.asarray(intensity)[finite].astype(np.float64))
        scale = np.percentile(grey, 99) if grey.size else 1.0
        grey = np.clip(grey / (scale if scale > 0 else 1.0), 0.0, 1.0)
        cloud.colors = o3d.utility.Vector3dVector(np.repeat(grey[:, None], 3, axis=1))
    if not o3d.io.write_point_cloud(Path(path), cloud, write_ascii=False):
        raise ValueError(f"{path}: open3d could not write the point cloud (is the suffix .ply/.pcd/.xyz?)")
    return int(np.count_nonzero(finite))
