"""Registration of a scene reference (``--reference scene:FILE``): the scene's rigid pose from the measured data.

1. The measured projector coordinate is triangulated with the rig (:class:`dptpu.fpp.triangulate.Triangulator`):
   the measured points (world frame).
2. The scene is ray cast by the twin at the file's pose (:func:`dptpu.sim.raycast.trace`): the surface the camera
   would see there, with its shading normals.
3. Point-to-plane ICP (open3d) moves the measured points onto that surface, from the file's pose, with the
   correspondence distance shrinking from 10 mm to 0.3 mm. Its inverse is the rigid change ``X -> R X + t``
   (world frame) that carries the file's scene to where the data put it: the registered pose (4, 4).
4. The scene is traced at the registered pose: its projector coordinate is the twin's, compared with the
   measurement as for a sphere or a plane (``residual_px`` = twin - measured; pixels off by more than
   ``OUTLIER_SIGMAS`` robust sigmas, e.g. wrong fringe orders, are left out of the fits).

The pose change is reported about the scene's centroid: the rotation angle (degrees) and axis, and the centroid's
displacement (rig units).
"""
from __future__ import annotations

import numpy as np

from dptpu.fpp.triangulate import Triangulator

from .candidates import add_camera_k1
from .reference import reference_hits
from .registration import MIN_OUTLIER_PX, OUTLIER_SIGMAS, Registration
from .selection import delta_bic, gain

__all__ = ["register_scene", "icp_pose", "pose_change", "fit_scene_lens_distortion", "ICP_DISTANCES_MM"]

#: Correspondence distances of the ICP passes, mm.
ICP_DISTANCES_MM = (10.0, 3.0, 1.0, 0.3)


def _point_cloud(points, normals=None):
    import open3d as o3d  # heavy: loaded on first use

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64)))
    if normals is not None:
        cloud.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(normals, dtype=np.float64))
    return cloud


def icp_pose(measured_points: np.ndarray, surface_points: np.ndarray, surface_normals: np.ndarray, *,
             mm: float = 1.0, distances_mm=ICP_DISTANCES_MM) -> np.ndarray:
    """Rigid transform (4, 4) carrying the surface (N, 3) onto the measured points (M, 3): point-to-plane
    ICP of the measured points onto the surface (its ``normals``), inverted; ``mm`` is one millimetre in the
    points' units."""
    import open3d as o3d  # heavy: loaded on first use

    registration = o3d.pipelines.registration
    source, target = _point_cloud(measured_points), _point_cloud(surface_points, surface_normals)
    transform = np.eye(4)
    criteria = registration.ICPConvergenceCriteria(relative_fitness=1e-9, relative_rmse=1e-9, max_iteration=60)
    for distance in distances_mm:
        result = registration.registration_icp(source, target, distance * mm, transform,
                                               registration.TransformationEstimationPointToPlane(), criteria)
        transform = np.asarray(result.transformation)
    return np.linalg.inv(transform)


def pose_change(pose: np.ndarray, centroid: np.ndarray) -> dict:
    """Rotation (angle in degrees, unit axis) and the displacement of ``centroid`` under ``pose`` (4, 4)."""
    R, t = pose[:3, :3], pose[:3, 3]
    angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    norm = np.linalg.norm(axis)
    return {"rotation_deg": angle, "rotation_axis": (axis / norm if norm > 0 else np.zeros(3)).tolist(),
            "centroid_translation": (R @ centroid + t - centroid).tolist()}


def _compare(rig, reference, pose, measured_x, mask, axis: int):
    hits = reference_hits(rig, reference, pose)
    model_x = np.where(hits.lit, hits.projector_xy[..., axis], np.nan)
    residual = model_x - measured_x
    return model_x, residual, mask & np.isfinite(residual)


def register_scene(rig, reference, measured_x: np.ndarray, mask: np.ndarray, *, period_px: float,
                   axis: str = "x") -> Registration:
    """The scene's registered pose (module docstring) as a :class:`~.registration.Registration` with ``pose``
    (4, 4) and ``pose_change``."""
    index = 0 if axis == "x" else 1
    mask = mask & np.isfinite(measured_x)
    points = Triangulator(rig, axis=axis).points(np.where(mask, measured_x, 0.0))[mask]
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) < 100:
        raise ValueError(f"scene registration needs at least 100 valid measured pixels; got {len(points)}")
    nominal = reference_hits(rig, reference, np.eye(4))
    seen = nominal.hit & np.all(np.isfinite(nominal.points), axis=-1)
    if seen.sum() < 100:
        raise ValueError(f"{reference.path}: the camera sees too little of the scene at the file's pose "
                         f"({int(seen.sum())} pixels)")
    mm = 1e-3 / rig.scale_to_m
    pose = icp_pose(points, nominal.points[seen], nominal.normals[seen], mm=mm)
    model_x, residual, fitted = _compare(rig, reference, pose, measured_x, mask, index)
    r = np.abs(residual[fitted])
    keep = np.zeros_like(fitted)
    keep[fitted] = r <= max(OUTLIER_SIGMAS * 1.4826 * float(np.median(r)), MIN_OUTLIER_PX)
    order_errors = float(np.mean(r > 0.5 * period_px)) if r.size else 0.0
    rms = float(np.sqrt(np.mean(residual[keep] ** 2))) if keep.any() else float("nan")
    centroid = np.vstack([m.vertices for m in reference.scene.meshes]).mean(axis=0)
    return Registration(pose=pose, extra=np.zeros(0), rig=rig, model_x=model_x,
                        residual_px=np.where(keep, residual, np.nan), rms_px=rms, pixels=int(keep.sum()), mask=keep,
                        order_errors=order_errors, pose_change=pose_change(pose, centroid))


def fit_scene_lens_distortion(rig, reference, measured_x: np.ndarray, registration: Registration, *,
                              step: float = 0.01, iterations: int = 3) -> tuple[dict, Registration]:
    """Camera ``k1`` the calibration lacks, on the phase residual with the registered pose held (a traced
    scene has no cheap pose derivative): Gauss-Newton with the derivative of one forward difference (the
    coordinate is nearly linear in ``k1`` at these sizes), ``iterations`` + 1 traces. Returns the entry and the
    geometry with it."""
    mask = registration.mask
    target = measured_x[mask]

    def residual(k1):
        hits = reference_hits(add_camera_k1(rig, [k1]), reference, registration.pose)
        r = hits.projector_xy[..., 0][mask] - target
        return np.where(np.isfinite(r) & hits.lit[mask], r, np.nan)

    r0 = residual(0.0)
    derivative = (residual(step) - r0) / step
    ok = np.isfinite(r0) & np.isfinite(derivative)
    rss0 = float(np.sum(r0[ok] ** 2))
    k1, r, best_rss = 0.0, r0, rss0
    for _ in range(iterations):
        good = ok & np.isfinite(r)
        trial = k1 - float(np.sum(r[good] * derivative[good]) / max(np.sum(derivative[good] ** 2), 1e-300))
        r_trial = residual(trial)
        rss = float(np.sum(np.where(ok & np.isfinite(r_trial), r_trial, r0) ** 2 * ok))
        if rss >= best_rss:
            break
        k1, r, best_rss = trial, r_trial, rss
    n = int(ok.sum())
    fitted_rig = add_camera_k1(rig, [k1])
    model_x, full, _ = _compare(fitted_rig, reference, registration.pose, measured_x, mask, 0)
    fitted = Registration(pose=registration.pose, extra=np.array([k1]), rig=fitted_rig, model_x=model_x,
                          residual_px=np.where(mask, full, np.nan), rms_px=float(np.sqrt(best_rss / max(n, 1))),
                          pixels=n, mask=mask)
    before, after = float(np.sqrt(rss0 / n)), float(np.sqrt(best_rss / n))
    entry = {"name": "lens_distortion", "parameters": {"camera": [k1, 0.0, 0.0, 0.0, 0.0], "projector": [0.0] * 5},
             "residual_before": before, "residual_after": after, "gain": gain(before, after),
             "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": 1,
                          "delta_bic": delta_bic(rss0, best_rss, n, 1), "camera_k1": k1,
                          "pose": "held at the scene registration"}}
    return entry, fitted
