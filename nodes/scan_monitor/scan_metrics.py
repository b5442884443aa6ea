"""How good one scan is against the twin's ground truth: valid points, fringe-order accuracy, depth error.

Pure numpy (no sockets): the scan monitor (:mod:`dptpu.nodes.scan_monitor`), the whole-graph tests and the
pipeline benchmark use the same definitions.

Definitions (H, W = camera height, width):

- valid points: pixels whose cloud point is finite;
- fringe-order accuracy: among pixels valid both in the scan's ``AbsolutePhase`` and in the ground truth, the
  fraction whose absolute phase is in the right fringe, ``round((Psi - Psi_true) / 2 pi) == 0`` (Eq. (3): a wrong
  fringe order ``k`` moves ``Psi`` by a multiple of ``2 pi``). Comparing ``Psi`` rather than ``k`` itself does not
  count a pixel whose wrapped phase sits on the 0 / 2 pi seam, where ``k`` and ``psi`` change together but
  ``Psi`` is right;
- depth error: ``z - z_true`` in millimetres over pixels with a finite point that the ground truth marks valid;
  ``depth_rms_mm`` over all of them, ``depth_rms_right_order_mm`` over those of the right fringe order (the
  phase noise alone).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["ScanMetrics", "scan_metrics"]

_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class ScanMetrics:
    """The figures of one scan (see the module docstring); NaN where no pixel qualifies."""

    valid_points: int
    total_pixels: int
    compared_pixels: int
    order_errors: int
    order_accuracy: float
    depth_pixels: int
    depth_rms_mm: float
    depth_rms_right_order_mm: float
    depth_max_abs_mm: float

    def as_dict(self) -> dict:
        return asdict(self)


def scan_metrics(depth_m: np.ndarray, absolute_phase: np.ndarray, phase_valid: np.ndarray,
                 truth_phase: np.ndarray, truth_valid: np.ndarray, truth_depth_m: np.ndarray) -> ScanMetrics:
    """Compare one scan with the ground truth.

    Parameters
    ----------
    depth_m : ndarray (H, W)
        The cloud's ``z`` in metres, NaN where no point.
    absolute_phase, phase_valid : ndarray (H, W)
        The scan's ``AbsolutePhase.absolute_phase`` (rad) and ``valid``.
    truth_phase, truth_valid : ndarray (H, W)
        True absolute phase of the same frequency (rad) and where it holds.
    truth_depth_m : ndarray (H, W)
        True depth, metres, NaN where no surface.

    Returns
    -------
    ScanMetrics
    """
    shapes = {np.shape(a) for a in (depth_m, absolute_phase, phase_valid, truth_phase, truth_valid, truth_depth_m)}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(f"depth, phase, truth and their masks must share one (H, W) shape; got {sorted(shapes)}")
    depth = np.asarray(depth_m, np.float64)
    truth_depth = np.asarray(truth_depth_m, np.float64)
    truth_valid = np.asarray(truth_valid, bool)
    finite = np.isfinite(depth)
    with np.errstate(invalid="ignore"):
        fringe_shift = np.rint((np.asarray(absolute_phase, np.float64) - truth_phase) / _TWO_PI)  # (H, W)
    compared = np.asarray(phase_valid, bool) & truth_valid & np.isfinite(fringe_shift)
    wrong = compared & (fringe_shift != 0)
    right = compared & ~wrong
    errors_mm = (depth - truth_depth) * 1e3  # (H, W)
    in_depth = finite & truth_valid & np.isfinite(truth_depth)

    def rms(mask) -> float:
        return float(np.sqrt(np.mean(errors_mm[mask] ** 2))) if mask.any() else float("nan")

    compared_count = int(np.count_nonzero(compared))
    wrong_count = int(np.count_nonzero(wrong))
    return ScanMetrics(
        valid_points=int(np.count_nonzero(finite)), total_pixels=int(depth.size), compared_pixels=compared_count,
        order_errors=wrong_count,
        order_accuracy=1.0 - wrong_count / compared_count if compared_count else float("nan"),
        depth_pixels=int(np.count_nonzero(in_depth)), depth_rms_mm=rms(in_depth),
        depth_rms_right_order_mm=rms(in_depth & right),
        depth_max_abs_mm=float(np.abs(errors_mm[in_depth]).max()) if in_depth.any() else float("nan"))
