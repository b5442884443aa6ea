"""The DP-TPU standard sphere (the paper's Fig. 3): its published figures and the project's own reconstruction.

Data: ``dptpu-sphere/`` (see its README): absolute phase of a real ceramic sphere (diameter 50.8082 mm) and of
its twin, with real and twin Bouguet calibrations. Two reconstructions are computed for each of the four
calibration/phase combinations:

- :func:`paper_reconstruction` repeats the paper's published script step by step: valid where
  ``|phase| >= 10``; projector column ``x_p - 1`` with ``x_p = phase / (2 pi 96) * 912``; one pinhole 3x3
  solve per pixel, no lens distortion; algebraic sphere fit; RMS of (distance to centre - radius).
- :func:`own_reconstruction` is the project's: the camera-projector pose refined over all nine calibration
  views instead of taken from view 1, the 0-based convention of docs/architecture.md (no ``- 1``), camera and
  projector lens distortion (:class:`~dptpu.fpp.triangulate.Triangulator`), a geometric sphere fit, and, as a
  second figure, the same after removing the unreliable edge band by a stated incidence rule.

See docs/real-sphere.md for the figures and every difference explained.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from .calibration import Rig, load_bouguet_pair
from .fitting import fit_sphere, fit_sphere_algebraic
from .mat_file import read_mat
from .triangulate import Triangulator, projector_coordinate

#: Certified diameter of the standard sphere, mm (data README / paper).
SPHERE_DIAMETER_MM = 50.8082
CAMERA_SIZE = (640, 480)
PROJECTOR_SIZE = (912, 1140)
FREQUENCY = 96
#: The paper's validity rule: ``|phase| >= 10`` rad (its script); 0 or NaN mark invalid pixels.
PAPER_MIN_PHASE = 10.0
#: Edge-band rule of the own reconstruction: keep points whose surface normal is within this angle of both
#: the camera ray and the projector ray (docs/real-sphere.md explains the choice).
MAX_INCIDENCE_DEG = 70.0

#: Fig. 3 of the paper, as labelled there: (calibration, phase) -> RMS in micrometres.
PAPER_FIGURES_UM = {("real", "real"): 58.541, ("twin", "real"): 61.999, ("real", "twin"): 32.125,
                    ("twin", "twin"): 28.256}

_CALIBRATION_FILES = {"real": ("CamCalibResult_real.mat", "PrjCalibResult_real.mat"),
                      "twin": ("CamCalibResult_sim.mat", "PrjCalibResult_sim.mat")}
_PHASE_FILES = {"real": ("standardball_phase_real.mat", "phase3"), "twin": ("standardball_phase_sim.mat", "phase")}
COMBINATIONS = (("real", "real"), ("twin", "real"), ("real", "twin"), ("twin", "twin"))


def combination_key(calibration: str, phase: str) -> str:
    """JSON key of a combination, e.g. ``calib_real_phase_twin``."""
    return f"calib_{calibration}_phase_{phase}"


@dataclass(frozen=True)
class SphereResult:
    rms_um: float
    radius_mm: float
    points: int

    def as_dict(self) -> dict:
        return {"rms_um": round(self.rms_um, 3), "radius_mm": round(self.radius_mm, 4), "points": self.points}


def load_rig(data_dir, calibration: str, *, relative_pose: str = "view") -> Rig:
    """The ``real`` or ``twin`` rig of the sphere data (Bouguet pair, world = calibration view 1, mm).

    ``relative_pose``: "view" takes both devices' extrinsics from view 1 (the paper); "all-views" refines the
    projector's pose relative to the camera over all nine views (:mod:`dptpu.fpp.stereo_calibration`).
    """
    if calibration not in _CALIBRATION_FILES:
        raise ValueError(f"calibration must be 'real' or 'twin'; got {calibration!r}")
    camera_file, projector_file = _CALIBRATION_FILES[calibration]
    data_dir = Path(data_dir)
    return load_bouguet_pair(data_dir / camera_file, data_dir / projector_file, camera_size=CAMERA_SIZE,
                             projector_size=PROJECTOR_SIZE, relative_pose=relative_pose)


def load_phase(data_dir, phase: str) -> np.ndarray:
    """Absolute phase (480, 640) float64 of the ``real`` or ``twin`` sphere, NaN where invalid
    (the paper's rule ``|phase| >= 10``)."""
    if phase not in _PHASE_FILES:
        raise ValueError(f"phase must be 'real' or 'twin'; got {phase!r}")
    name, field = _PHASE_FILES[phase]
    path = Path(data_dir) / name
    data = read_mat(path, what="phase file")
    if field not in data:
        raise ValueError(f"{path}: missing field '{field}'")
    values = np.asarray(data[field], dtype=np.float64)
    expected = CAMERA_SIZE[::-1]
    if values.shape != expected:
        raise ValueError(f"{path}: field '{field}' must have shape {expected}; got {values.shape}")
    with np.errstate(invalid="ignore"):
        return np.where(np.abs(values) >= PAPER_MIN_PHASE, values, np.nan)


def paper_reconstruction(rig: Rig, phase: np.ndarray) -> SphereResult:
    """The paper's published reconstruction (``Cross_reconstruction.m``), reproduced step by step."""
    valid = np.isfinite(phase)
    projector_x = projector_coordinate(phase, FREQUENCY, PROJECTOR_SIZE[0]) - 1.0  # the script's "x_p - 1"
    points = Triangulator(rig, distortion=False).points(projector_x)[valid]
    fit = fit_sphere_algebraic(points)
    return SphereResult(fit.rms * 1e3, fit.radius, int(valid.sum()))


def incidence_angles_deg(rig: Rig, points: np.ndarray, center: np.ndarray) -> np.ndarray:
    """Largest of the angles between the sphere normal and the rays to camera and projector, degrees, (M,)."""
    normals = points - center
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    cosines = []
    for device in (rig.camera, rig.projector):
        to_device = device.center - points
        to_device /= np.linalg.norm(to_device, axis=1, keepdims=True)
        cosines.append(np.einsum("ij,ij->i", normals, to_device))
    return np.degrees(np.arccos(np.clip(np.minimum(*cosines), -1.0, 1.0)))


def own_reconstruction(rig: Rig, phase: np.ndarray) -> tuple[SphereResult, SphereResult]:
    """The project's reconstruction: (all valid pixels, edge band removed by the incidence rule)."""
    valid = np.isfinite(phase)
    projector_x = projector_coordinate(phase, FREQUENCY, PROJECTOR_SIZE[0])
    points = Triangulator(rig).points(projector_x)[valid]
    fit_all = fit_sphere(points)
    kept = points[incidence_angles_deg(rig, points, fit_all.center) <= MAX_INCIDENCE_DEG]
    fit_kept = fit_sphere(kept)
    return (SphereResult(fit_all.rms * 1e3, fit_all.radius, len(points)),
            SphereResult(fit_kept.rms * 1e3, fit_kept.radius, len(kept)))


def evaluate(data_dir, *, progress: bool = False) -> dict[str, dict[str, Any]]:
    """All figures of ``dptpu eval sphere``: the paper's method and ours for the four combinations (``progress``: a
    tqdm bar over them on stderr)."""
    data_dir = Path(data_dir)
    if not data_dir.is_dir():
        raise FileNotFoundError(f"{data_dir}: sphere data folder not found (expected ../shared/data/dptpu-sphere)")
    rigs = {name: load_rig(data_dir, name) for name in ("real", "twin")}
    refined_rigs = {name: load_rig(data_dir, name, relative_pose="all-views") for name in ("real", "twin")}
    phases = {name: load_phase(data_dir, name) for name in ("real", "twin")}
    report: dict[str, dict[str, Any]] = {"paper": {}, "ours": {}, "paper_figures_um": {}}
    for calibration, phase in tqdm(COMBINATIONS, desc="reconstructing the sphere", unit="combination",
                                   disable=not progress, file=sys.stderr):
        key = combination_key(calibration, phase)
        report["paper"][key] = round(paper_reconstruction(rigs[calibration], phases[phase]).rms_um, 3)
        report["paper_figures_um"][key] = PAPER_FIGURES_UM[(calibration, phase)]
        all_points, edge_removed = own_reconstruction(refined_rigs[calibration], phases[phase])
        report["ours"][key] = {**all_points.as_dict(),
                               "edge_band_removed": {**edge_removed.as_dict(),
                                                     "rule": f"incidence <= {MAX_INCIDENCE_DEG:g} deg"}}
    return report
