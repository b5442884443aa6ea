"""Network inputs from the DP-TPU real sphere: the real high-frequency phase and a synthesized 3-step low phase.

Data: ``../shared/data/dptpu-sphere`` (:mod:`dptpu.fpp.real_sphere`): the absolute phase ``phi`` of a real ceramic
sphere at ``f_h = 96`` periods over the 912 px projector (12-step, three-frequency TPU), with the real calibration.
No frames and no low-frequency phase were published, so the MF pair (``f_l = 1``, the paper's Eq. (5)) is:

- **wrapped_high** (real): ``psi_h = mod(phi, 2 pi)``, the measured 12-step wrapped phase.
- **reference order** (real): ``floor(phi / 2 pi)``, the measured order (``Round((phi - psi_h) / 2 pi)``).
- **wrapped_low** (synthesized): the 3-step frames of ``f_l = 1`` at the MEASURED phase, ``psi_l* = phi / 96``:
  ``I_n = A + B cos(psi_l* - 2 pi n / 3) + noise`` (Eq. (1)), with the background ``A`` and modulation ``B``
  (DN) of the twin's own rendering of the registered sphere (the analytic sphere of the certified diameter at
  the centre fitted to ``phi``, :mod:`.registration`; baseline twin, no effects), Gaussian camera noise of
  ``noise_sigma`` DN (the paper's 1 sigma = 1.5693, 2 sigma = 3.1386), quantized to 8 bits; ``psi_l`` by Eq. (2).
- **valid**: the measured phase is valid (``|phi| >= 10``, the paper's rule), the twin's sphere covers the pixel,
  and the synthesized frames pass the quality mask.

3D error (:func:`sphere_errors_um`): the points triangulated from ``psi_h + 2 pi k`` with the real calibration
(camera-projector pose refined over all views, lens distortion), a geometric sphere fit with a free radius, on
all valid pixels and on the interior (the 2 px edge band left out).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dptpu.fpp import real_sphere
from dptpu.fpp.fitting import fit_sphere
from dptpu.fpp.phase import quality_mask, wrapped_phase
from dptpu.fpp.triangulate import Triangulator
from dptpu.sim.image_formation import SequenceSpec, quantize, render_frames_float
from dptpu.sim.scenes import load_scene

from .measured_pair import MeasuredPair, mf_coarse_order, reference_order
from .pixels import erode_mask
from .reference import Reference
from .registration import register
from .rerender import analytic_samples

__all__ = ["sphere_pair", "sphere_errors_um", "twin_levels", "EDGE_BAND_PX", "FREQUENCY_HIGH"]

FREQUENCY_HIGH = float(real_sphere.FREQUENCY)
EDGE_BAND_PX = 2
_TWO_PI = 2.0 * np.pi
_MIN_MODULATION_FRACTION = 0.02


def twin_levels(rig, phase: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Background ``A`` and modulation ``B`` (H, W) DN of the baseline twin's sphere registered to ``phase``.

    NaN where the twin's sphere does not cover the pixel. The pose is fitted on the measured interior
    (2 px edge band left out), as the diagnosis does.
    """
    reference = Reference("sphere", diameter=real_sphere.SPHERE_DIAMETER_MM)
    valid = np.isfinite(phase)
    projector_x = np.where(valid, phase, 0.0) * real_sphere.PROJECTOR_SIZE[0] / (_TWO_PI * FREQUENCY_HIGH)
    registration = register(rig, reference, np.where(valid, projector_x, np.nan), erode_mask(valid, EDGE_BAND_PX))
    material = load_scene("sphere", rig).meshes[0].material
    samples = analytic_samples(rig, reference, registration.pose, material)
    frames = render_frames_float(rig, samples, [SequenceSpec(1.0, 12)], effects=[])[0]  # (12, H, W), no noise
    maps = wrapped_phase(frames)
    covered = samples.lit & samples.hit
    return np.where(covered, maps.background, np.nan), np.where(covered, maps.modulation, np.nan)


def sphere_pair(data_dir, *, noise_sigma: float, seed: int = 0, rig=None, levels=None) -> MeasuredPair:
    """The MF pair of the real sphere at one camera-noise level (module docstring).

    Parameters
    ----------
    data_dir : path
        ``../shared/data/dptpu-sphere``.
    noise_sigma : float
        Camera noise of the synthesized low-frequency frames, DN (>= 0).
    seed : int
        Seed of the noise draw.
    rig : Rig, optional
        The real rig (default: the real Bouguet pair, pose refined over all views).
    levels : (ndarray, ndarray), optional
        ``(A, B)`` from :func:`twin_levels` (computed when not given).
    """
    if not (np.isfinite(noise_sigma) and noise_sigma >= 0):
        raise ValueError(f"noise_sigma must be >= 0 (DN); got {noise_sigma!r}")
    data_dir = Path(data_dir)
    phase = real_sphere.load_phase(data_dir, "real")  # (480, 640), NaN invalid
    rig = rig if rig is not None else real_sphere.load_rig(data_dir, "real", relative_pose="all-views")
    background, modulation = levels if levels is not None else twin_levels(rig, phase)
    measured = np.isfinite(phase) & np.isfinite(background)
    psi_h = np.where(measured, np.mod(phase, _TWO_PI), 0.0)
    low_true = np.where(measured, phase / FREQUENCY_HIGH, 0.0)  # phase of f_l = 1, absolute
    shifts = _TWO_PI * np.arange(3) / 3.0
    rng = np.random.default_rng(seed)
    clean = np.where(measured, background, 0.0) + np.where(measured, modulation, 0.0) * np.cos(
        low_true[None] - shifts[:, None, None])  # Eq. (1), (3, H, W)
    frames = quantize(clean + rng.normal(0.0, float(noise_sigma), clean.shape), 8)
    maps = wrapped_phase(frames)
    usable = quality_mask(frames, maps.modulation, min_modulation=_MIN_MODULATION_FRACTION * 255.0)
    valid = measured & usable
    psi_l = np.where(valid, maps.phase, 0.0)
    psi_h = np.where(valid, psi_h, 0.0)
    phi_ref = np.where(valid, phase, np.nan)
    return MeasuredPair(
        name=f"sphere_sigma{noise_sigma:g}", wrapped_high=psi_h, wrapped_low=psi_l,
        coarse_order=mf_coarse_order(psi_h, psi_l, FREQUENCY_HIGH, valid),
        reference_order=reference_order(phi_ref, psi_h), reference_phase=phi_ref, valid=valid,
        frequency_high=FREQUENCY_HIGH, frequency_low=1.0, method="mf", extent_px=real_sphere.PROJECTOR_SIZE[0],
        provenance={
            "data": "DP-TPU real sphere (standardball_phase_real.mat, real calibration)",
            "wrapped_high": "real: mod(phi, 2 pi) of the measured 12-step absolute phase at f_h = 96",
            "wrapped_low": f"synthesized: 3-step frames of f_l = 1 at the measured phase phi / 96, the baseline "
                           f"twin's A and B on the registered sphere, Gaussian noise {noise_sigma:g} DN, 8 bit",
            "method": "mf (Eq. 5), f_h / f_l = 96",
            "reference": "real: floor(phi / 2 pi) of the measured absolute phase",
        })


def sphere_errors_um(pair: MeasuredPair, order, rig) -> dict:
    """3D error of a reconstruction of the sphere with fringe orders ``order`` (H, W).

    Returns
    -------
    dict
        ``sphere_rms_um`` and ``radius_mm`` (geometric fit, free radius) on all valid pixels and, as
        ``interior_*``, with the 2 px edge band left out; ``point_error_rms_um``: RMS distance between the points of
        ``order`` and those of the reference order (0 when every order is right), over all valid pixels;
        ``points``.
    """
    triangulator = Triangulator(rig)
    out = {}
    for prefix, mask in (("", pair.valid), ("interior_", erode_mask(pair.valid, EDGE_BAND_PX))):
        points = triangulator.points(np.where(mask, pair.projector_x(order), 0.0))[mask]
        points = points[np.all(np.isfinite(points), axis=1)]
        fit = fit_sphere(points)
        out[f"{prefix}sphere_rms_um"] = float(fit.rms * 1e3)
        out[f"{prefix}radius_mm"] = float(fit.radius)
        out[f"{prefix}points"] = int(len(points))
    ours = triangulator.points(np.where(pair.valid, pair.projector_x(order), 0.0))[pair.valid]
    truth = triangulator.points(np.where(pair.valid, pair.projector_x(pair.reference_order), 0.0))[pair.valid]
    distance = np.linalg.norm(ours - truth, axis=1)
    distance = distance[np.isfinite(distance)]
    out["point_error_rms_um"] = float(np.sqrt(np.mean(distance ** 2)) * 1e3)
    return out
