"""Does the absolute phase run the way the rig says it must? A check of a capture's ``phase_shift_sign``.

A wrong ``phase_shift_sign`` negates every wrapped phase (``psi -> -psi``, the paper's Eq. (2) with the
steps taken backwards). Temporal unwrapping of negated phases stays self-consistent (every frequency is
negated alike), so the result looks valid but is the mirror image ``x_p -> W - x_p`` of the projector: wrong
orders everywhere, wrong depth. What gives it away is the direction: along a camera row or column the
projector coordinate seen by the camera changes in the sense the rig's geometry fixes, and a mirrored phase
changes the other way.

The expected sense comes from the infinite homography ``H = K_p R_p R_c^T K_c^-1`` (camera pixel to projector
pixel for points far away, Hartley and Zisserman, "Multiple View Geometry", 2nd ed., Eq. (13.6)). The depth
term it leaves out shifts the projector coordinate but does not turn it around for a visible surface: along an
epipolar line the order of points is kept unless one device sees the surface from behind (the ordering
constraint). Lens distortion is left out too; it bends but does not reverse the direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .calibration import load_rig
from .capture.model import CAPTURE_FILE, Capture
from .rig_model import Rig

__all__ = ["PhaseDirectionVote", "phase_direction_vote", "check_capture_phase_direction"]


@dataclass(frozen=True)
class PhaseDirectionVote:
    """Neighbouring valid pixels voting on the sense of the absolute phase.

    Attributes
    ----------
    agreement : float
        Fraction in ``[0, 1]`` of the votes (weighted by the expected change, below) for the rig's sense;
        NaN when no pair voted.
    pairs : int
        Neighbouring pairs of valid pixels that voted (their phase differs).
    for_weight, against_weight : float
        Summed weights of the votes for and against.
    chance_spread : float
        ``sqrt(sum of squared weights)``: the standard deviation of ``for_weight - against_weight`` if every
        vote were a fair coin (phase noise alone).

    Notes
    -----
    A pair is two valid neighbours along a camera row or column. Its vote is the sign of
    ``dPhi * dx_p``: the measured change of absolute phase times the change of the projector coordinate that
    the rig predicts for the same step, weighted by ``|dx_p|`` (projector pixels), so that the axis along
    which the fringes run decides, not the one along which they barely change.
    """

    agreement: float
    pairs: int
    for_weight: float
    against_weight: float
    chance_spread: float

    @property
    def contradicts(self) -> bool:
        """True when the pixels vote against the rig's sense beyond chance: the weight against exceeds the
        weight for by more than three ``chance_spread`` (three standard deviations of coin-flip votes)."""
        return self.pairs > 0 and self.against_weight - self.for_weight > 3.0 * self.chance_spread


def phase_direction_vote(absolute_phase: np.ndarray, valid: np.ndarray, rig: Rig, fringe_axis: str
                         ) -> PhaseDirectionVote:
    """Vote, pixel pair by pixel pair, on whether ``absolute_phase`` increases the way ``rig`` predicts.

    Parameters
    ----------
    absolute_phase : ndarray (H, W) float
        Absolute phase ``Phi = 2 pi f x_p / W`` (any scale: only differences' signs count); ignored where not
        ``valid``.
    valid : ndarray (H, W) bool
    rig : Rig
        Its camera's ``size`` must be ``(W, H)``.
    fringe_axis : {"x", "y"}
        The projector axis along which the phase varies.

    Returns
    -------
    PhaseDirectionVote
        ``agreement`` near 1 for a correctly signed capture, near 0 for a mirrored one (the module's Notes).

    Convention: pixel centres are 0-based; ``x_p`` is the projector pixel coordinate along ``fringe_axis``.
    """
    phase = np.asarray(absolute_phase, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    if phase.ndim != 2 or valid.shape != phase.shape:
        raise ValueError(f"absolute_phase and valid must both have shape (H, W); got {phase.shape} and {valid.shape}")
    if tuple(rig.camera.size) != (phase.shape[1], phase.shape[0]):
        raise ValueError(f"the rig's camera is {rig.camera.size[0]}x{rig.camera.size[1]}; the phase is "
                         f"{phase.shape[1]}x{phase.shape[0]}")
    if fringe_axis not in ("x", "y"):
        raise ValueError(f"fringe_axis must be 'x' or 'y'; got {fringe_axis!r}")
    expected = _projector_coordinate_at_infinity(rig, fringe_axis)  # (H, W), NaN behind the projector
    usable = valid & np.isfinite(phase) & np.isfinite(expected)
    for_weight = against_weight = squared_weight = 0.0
    pairs = 0
    for axis in (0, 1):  # camera rows (v), then columns (u)
        measured = np.diff(phase, axis=axis)  # (H-1, W) or (H, W-1)
        predicted = np.diff(expected, axis=axis)
        both = _pairs(usable, axis) & (measured != 0)
        vote = np.sign(measured[both]) * np.sign(predicted[both])
        weight = np.abs(predicted[both])
        for_weight += float(weight[vote > 0].sum())
        against_weight += float(weight[vote < 0].sum())
        squared_weight += float(np.square(weight[vote != 0]).sum())
        pairs += int(both.sum())
    total = for_weight + against_weight
    agreement = for_weight / total if total > 0 else float("nan")
    return PhaseDirectionVote(agreement=agreement, pairs=pairs, for_weight=for_weight, against_weight=against_weight,
                              chance_spread=float(np.sqrt(squared_weight)))


def check_capture_phase_direction(capture: Capture, absolute_phase: np.ndarray, valid: np.ndarray
                                  ) -> PhaseDirectionVote | None:
    """Refuse a capture whose unwrapped phase contradicts its ``phase_shift_sign`` (the rig's sense, above).

    Parameters
    ----------
    capture : Capture
        With a ``calibration`` rig file; without one (or with a rig of other device sizes, which the
        commands that triangulate refuse themselves) nothing is checked and None is returned.
    absolute_phase, valid : ndarray (H, W)
        The unwrapped result of the capture.

    Returns
    -------
    PhaseDirectionVote or None

    Raises
    ------
    ValueError
        ``capture.yaml: phase_shift_sign -1 contradicts the frames: ...``, naming the share of pixel pairs
        against the rig and the sign the frames show (:attr:`PhaseDirectionVote.contradicts`).
    """
    if capture.calibration is None:
        return None
    rig = load_rig(capture.calibration)
    if (tuple(rig.camera.size) != tuple(capture.camera_size)
            or tuple(rig.projector.size) != tuple(capture.projector_size)):
        return None
    vote = phase_direction_vote(absolute_phase, valid, rig, capture.fringe_axis)
    if vote.contradicts:
        sign = capture.phase_shift_sign
        raise ValueError(f"{capture.root / CAPTURE_FILE}: phase_shift_sign {sign:+d} contradicts the frames: the "
                         f"absolute phase runs against the projector's {capture.fringe_axis} axis as the rig "
                         f"{capture.calibration.name} sees it at {100 * (1 - vote.agreement):.1f} % of "
                         f"{vote.pairs} neighbouring pixel pairs; the frames look like phase_shift_sign {-sign:+d}")
    return vote


def _projector_coordinate_at_infinity(rig: Rig, fringe_axis: str) -> np.ndarray:
    """``x_p`` (or ``y_p``) of every camera pixel through the infinite homography, (H, W); NaN where the ray at
    infinity lies behind the projector."""
    width, height = rig.camera.size
    homography = rig.projector.K @ rig.projector.R @ rig.camera.R.T @ np.linalg.inv(rig.camera.K)  # (3, 3)
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))  # (H, W)
    pixels = np.stack([u, v, np.ones_like(u)], axis=-1)  # (H, W, 3)
    mapped = pixels @ homography.T  # (H, W, 3)
    row = 0 if fringe_axis == "x" else 1
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(mapped[..., 2] > 0, mapped[..., row] / mapped[..., 2], np.nan)


def _pairs(usable: np.ndarray, axis: int) -> np.ndarray:
    """Both pixels of each neighbouring pair along ``axis`` usable, shape of ``np.diff(usable, axis=axis)``."""
    if axis == 0:
        return usable[1:, :] & usable[:-1, :]
    return usable[:, 1:] & usable[:, :-1]
