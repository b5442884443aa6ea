"""How good one scan is against the twin's ground truth: valid points, fringe-order accuracy, depth error,
precision and completeness, and whether the scan can be trusted.

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
  phase noise alone);
- precision and completeness (:mod:`dptpu.fpp.cloud_accuracy`, the definition ``dptpu eval cloud`` uses too):
  ``wrong_share`` = published points (finite) with a wrong fringe order or off the true surface / published
  points, ``completeness`` = published points the truth marks valid / pixels the truth marks valid;
- the verdict (:func:`trust_verdict`): a scan is trusted when ``wrong_share <= max_wrong_share`` and
  ``completeness >= min_completeness`` (the scan monitor's parameters; defaults and the measurements behind them
  in docs/scanner.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from dptpu.fpp.cloud_accuracy import NOISE_SIGMAS, OFF_SURFACE_MM, cloud_accuracy, order_shift

__all__ = ["MAX_WRONG_SHARE", "MIN_COMPLETENESS", "ScanMetrics", "scan_metrics", "trust_verdict"]

#: Default bound of a trusted scan: at most this share of its published points wrong (issue #16's goal, 0.1 %).
MAX_WRONG_SHARE = 0.001
#: Default bound of a trusted scan: at least this share of the truly valid pixels published (docs/scanner.md).
MIN_COMPLETENESS = 0.50



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
    truly_valid_pixels: int = 0
    published_truly_valid: int = 0
    wrong_order_points: int = 0
    off_surface_points: int = 0
    wrong_points: int = 0
    wrong_share: float = float("nan")
    completeness: float = float("nan")
    off_surface_tolerance_mm: float = float("nan")

    def as_dict(self) -> dict:
        # not dataclasses.asdict: its fields() makes a tuple from a generator on every call, which CPython's tuple
        # free list keeps when freed (2,000 of them, 350 KB, over the first scans: issue 19's soak)
        return {name: getattr(self, name) for name in _FIELD_NAMES}


_FIELD_NAMES = tuple([item.name for item in fields(ScanMetrics)])


def scan_metrics(depth_m: np.ndarray, absolute_phase: np.ndarray, phase_valid: np.ndarray,
                 truth_phase: np.ndarray, truth_valid: np.ndarray, truth_depth_m: np.ndarray, *,
                 off_surface_mm: float = OFF_SURFACE_MM, noise_sigmas: float = NOISE_SIGMAS) -> ScanMetrics:
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
    off_surface_mm, noise_sigmas : float
        A point of the right order is off the surface beyond ``max(off_surface_mm, noise_sigmas * sigma)``
        (:func:`dptpu.fpp.cloud_accuracy.cloud_accuracy`).

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
    fringe_shift = order_shift(absolute_phase, truth_phase)  # (H, W)
    compared = np.asarray(phase_valid, bool) & truth_valid & np.isfinite(fringe_shift)
    wrong = compared & (fringe_shift != 0)
    right = compared & ~wrong
    errors_mm = (depth - truth_depth) * 1e3  # (H, W)
    in_depth = finite & truth_valid & np.isfinite(truth_depth)

    def rms(mask) -> float:
        return float(np.sqrt(np.mean(errors_mm[mask] ** 2))) if mask.any() else float("nan")

    accuracy = cloud_accuracy(finite, truth_valid, shift=np.where(compared, fringe_shift, np.nan),
                              depth=depth * 1e3, truth_depth=truth_depth * 1e3, off_surface=off_surface_mm,
                              noise_sigmas=noise_sigmas)
    compared_count = int(np.count_nonzero(compared))
    wrong_count = int(np.count_nonzero(wrong))
    return ScanMetrics(
        valid_points=int(np.count_nonzero(finite)), total_pixels=int(depth.size), compared_pixels=compared_count,
        order_errors=wrong_count,
        order_accuracy=1.0 - wrong_count / compared_count if compared_count else float("nan"),
        depth_pixels=int(np.count_nonzero(in_depth)), depth_rms_mm=rms(in_depth),
        depth_rms_right_order_mm=rms(in_depth & right),
        depth_max_abs_mm=float(np.abs(errors_mm[in_depth]).max()) if in_depth.any() else float("nan"),
        truly_valid_pixels=accuracy.truly_valid, published_truly_valid=accuracy.published_truly_valid,
        wrong_order_points=accuracy.wrong_order,
        off_surface_points=accuracy.off_surface, wrong_points=accuracy.wrong, wrong_share=accuracy.wrong_share,
        completeness=accuracy.completeness, off_surface_tolerance_mm=accuracy.off_surface_tolerance)


def trust_verdict(wrong_share: float, completeness: float, *, max_wrong_share: float = MAX_WRONG_SHARE,
                  min_completeness: float = MIN_COMPLETENESS) -> str:
    """Why a scan is not to be trusted, or "" when it is within both bounds.

    ``"5.93 % of the points wrong (> 0.10 %)"``, ``"completeness 71.2 % (< 80.0 %)"``, both joined by ``"; "``, or
    ``"no point published"`` (NaN shares).
    """
    if not (math.isfinite(wrong_share) and math.isfinite(completeness)):
        return "no point published" if not math.isfinite(wrong_share) else "no truly valid pixel to compare"
    reasons = []
    if wrong_share > max_wrong_share:
        reasons.append(f"{100 * wrong_share:.2f} % of the points wrong (> {100 * max_wrong_share:.2f} %)")
    if completeness < min_completeness:
        reasons.append(f"completeness {100 * completeness:.1f} % (< {100 * min_completeness:.1f} %)")
    return "; ".join(reasons)
