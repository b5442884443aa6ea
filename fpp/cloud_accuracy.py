"""How far a published cloud can be trusted against ground truth: precision (wrong points) and completeness.

One definition for the scan monitor (:mod:`dptpu.nodes.scan_monitor`) and ``dptpu eval cloud``
(:mod:`dptpu.experiments.cloud_eval`). Per pixel of one scan (H, W):

- **published**: the pixels whose point the scanner gives out (a finite point after every filter);
- **truly valid**: the pixels the ground truth marks as seen by the camera and lit by the projector;
- **wrong order**: a published pixel whose fringe order differs from the truth's (``order_shift != 0``, where
  ``order_shift = round((Phi - Phi_true) / 2 pi)``; a wrong order moves the point by whole fringe periods, Eq. (3));
- **off the surface**: a published pixel of the right (or unknown) order whose depth is more than
  ``tolerance`` from the true depth along its ray, or that has no true surface at all (a point in the air):
  flying points between a foreground and a background, points in shadows, noise far beyond the rest;
- **wrong** = wrong order + off the surface; ``wrong_share = wrong / published`` (1 - precision);
- **completeness** = published and truly valid / truly valid.

The tolerance is ``max(off_surface, noise_sigmas * sigma)``, ``sigma`` the scan's own depth noise (1.4826 times the
median absolute deviation of the depth error over the published pixels of the right order): a fixed floor
(default 1 mm, the issue's "more than 1 mm from every true surface") that grows on a noisier rig, so that the noise
a rig's fringes give every point is not called wrong, and a point many of its sigmas away is. The depth error is
taken along the camera's ``z``: on a surface seen at a slant it is larger than the distance to the surface, so the
count errs on the side of calling a point wrong. Where no depth truth exists (real captures scored against a
reference fringe order) only the order counts.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["NOISE_SIGMAS", "OFF_SURFACE_MM", "CloudAccuracy", "cloud_accuracy", "order_shift"]

#: Smallest depth error, mm, that makes a point of the right order "off the surface".
OFF_SURFACE_MM = 1.0
#: A point this many of the scan's depth-noise sigmas from the true depth is off the surface, if above the floor.
NOISE_SIGMAS = 6.0
_MAD_TO_SIGMA = 1.4826  # sigma of a normal distribution per median absolute deviation


@dataclass(frozen=True)
class CloudAccuracy:
    """The counts of one scan (module docstring); shares are NaN where their denominator is 0."""

    published: int
    truly_valid: int
    published_truly_valid: int
    wrong_order: int
    off_surface: int
    off_surface_tolerance: float

    @property
    def wrong(self) -> int:
        """Published points with a wrong order or off the surface."""
        return self.wrong_order + self.off_surface

    @property
    def wrong_share(self) -> float:
        """``wrong / published`` (1 - precision)."""
        return self.wrong / self.published if self.published else float("nan")

    @property
    def completeness(self) -> float:
        """``published and truly valid / truly valid``."""
        return self.published_truly_valid / self.truly_valid if self.truly_valid else float("nan")

    def as_dict(self) -> dict:
        return dict(asdict(self), wrong=self.wrong, wrong_share=self.wrong_share, completeness=self.completeness)


def order_shift(absolute_phase: np.ndarray, truth_phase: np.ndarray) -> np.ndarray:
    """``round((Phi - Phi_true) / 2 pi)``, float (H, W): the fringe orders a pixel is off; NaN where either is."""
    with np.errstate(invalid="ignore"):
        return np.rint((np.asarray(absolute_phase, np.float64) - np.asarray(truth_phase, np.float64)) / (2 * np.pi))


def cloud_accuracy(published, truly_valid, *, shift=None, depth=None, truth_depth=None,
                   off_surface: float = OFF_SURFACE_MM, noise_sigmas: float = NOISE_SIGMAS) -> CloudAccuracy:
    """Precision and completeness of one scan's published points.

    Parameters
    ----------
    published, truly_valid : ndarray (H, W) bool
        The pixels given out, and those the truth marks seen and lit.
    shift : ndarray (H, W), optional
        :func:`order_shift` of the scan's absolute phase against the truth's; NaN where there is no comparison.
        None: orders are not judged.
    depth, truth_depth : ndarray (H, W), optional
        The published depth and the true depth (NaN where no surface), in the units of ``off_surface``. None: the
        depth is not judged (real captures).
    off_surface, noise_sigmas : float
        The tolerance (module docstring): ``max(off_surface, noise_sigmas * sigma)``.

    Returns
    -------
    CloudAccuracy
    """
    published = np.asarray(published, bool)
    truly_valid = np.asarray(truly_valid, bool)
    arrays = [published, truly_valid] + [np.asarray(a) for a in (shift, depth, truth_depth) if a is not None]
    shapes = {a.shape for a in arrays}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(f"published, truly_valid, shift and depths must share one (H, W) shape; got {sorted(shapes)}")
    if (depth is None) != (truth_depth is None):
        raise ValueError("depth and truth_depth come together (both or neither)")
    if not (off_surface >= 0 and noise_sigmas >= 0):
        raise ValueError(f"off_surface and noise_sigmas must be >= 0; got {off_surface}, {noise_sigmas}")
    wrong_order = np.zeros_like(published)
    if shift is not None:
        shift = np.asarray(shift, np.float64)
        wrong_order = published & np.isfinite(shift) & (shift != 0)
    off = np.zeros_like(published)
    tolerance = float("nan")
    if depth is not None and truth_depth is not None:
        error = np.asarray(depth, np.float64) - np.asarray(truth_depth, np.float64)  # (H, W)
        has_truth = np.isfinite(error)
        right = published & has_truth & ~wrong_order
        tolerance = float(off_surface)
        if right.any():
            centred = error[right] - np.median(error[right])
            tolerance = max(tolerance, noise_sigmas * _MAD_TO_SIGMA * float(np.median(np.abs(centred))))
        with np.errstate(invalid="ignore"):
            off = published & ~wrong_order & (~has_truth | (np.abs(error) > tolerance))
    return CloudAccuracy(published=int(np.count_nonzero(published)), truly_valid=int(np.count_nonzero(truly_valid)),
                         published_truly_valid=int(np.count_nonzero(published & truly_valid)),
                         wrong_order=int(np.count_nonzero(wrong_order)), off_surface=int(np.count_nonzero(off)),
                         off_surface_tolerance=tolerance)
