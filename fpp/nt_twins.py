"""Near-twins of a number-theoretic (NT) frequency pair: fringe orders far apart whose phases nearly agree.

NT (Eqs. (8)-(9) of the paper) tells the pairs ``(k_h, k_l)`` apart by their keys, but the keys of some pairs lie
close together. Moving the high order by ``m`` at the same wrapped phase ``psi_h`` moves the low phase that Eq. (3)
predicts by ``2 pi f_l m / f_h``; with the low order moved by ``n = Round(f_l m / f_h)`` the prediction moves by

    s_m = 2 pi (f_l m / f_h - n)                            (radians of the low phase)

only. Where ``|s_m|`` is small the pair ``(k_h + m, k_l + n)`` is a *near-twin* of ``(k_h, k_l)``: for ``64 / 10.9``,
``m = 47`` gives ``10.9 * 47 / 64 = 8.0047`` low periods, ``s = 0.0295`` rad. Both pairs occur on the projector where
both projector columns ``x`` and ``x + m W / f_h`` do: the first and the last ``1 - m / f_h`` of it (26.6 % each
for ``m = 47``).
:func:`near_twins` lists a pair's twins (every ``m`` in ``1 .. ceil(f_h) - 1``; ``-m`` is the same twin seen
from the other side, ``s_{-m} = -s_m``); it depends on the two frequencies alone (the extent cancels).

**The decision against a twin.** With the published order's low-phase residual
``eps = wrap((f_l / f_h) Phi_h - psi_l)`` (:func:`dptpu.fpp.frequency_consistency.consistency_residual`), the twin's
residual is ``eps + s_m``, so the published order is the likelier of the two while ``u = sign(s_m) eps > -|s_m| / 2``,
and its margin in the pixel's own noise ``sigma`` (the standard deviation of ``eps``) is

    z_pixel = (u + |s_m| / 2) / sigma.

A twin that noise can reach (``|s_m| / 2 < Z sigma``; :func:`reachable_twins`) leaves many pixels with a small
``z_pixel``: one pixel cannot tell the twins apart. A *region* decided as a whole can (DP-TPU's band prior,
:mod:`dptpu.models.nt_prior`, decides the low order of a band at once): over the ``n`` pixels of a connected region of
one low order of the published phase, ``floor((f_l / f_h) Phi_h / 2 pi)``, where the twin lies on the projector, the
median of ``u`` has the standard error ``sqrt(pi / 2) sigma_R / sqrt(n)`` (``sigma_R`` the larger of the region's
robust spread, its interquartile range over 1.349, and the scan's), so

    z_region = (median(u) + |s_m| / 2) / (sqrt(pi / 2) sigma_R / sqrt(n)),

the region's margin against the twin in standard errors (the region test of
:func:`dptpu.fpp.region_consistency.rejected_regions`, against a twin instead of one order off). A region whose pixels
lie at two different wrong orders (a band that joined two surfaces, each taken to a twin: the band prior's failure on an
outside capture, where one published low order held pixels 47 and 41 high orders off) has a median between the two that
can clear the boundary; such a region is seen locally, where each surface is alone. Its two offsets also widen the
region's spread of ``u`` beyond what its pixels' noise gives one surface, dim or bright: the region's mixture margin

    z_mixture = (IQR(u) / 1.349 / median(sigma_p) - 1) sqrt(n) / 1.166

(1.166 sigma / sqrt(n): the standard error of the interquartile range over 1.349; the median of ``sigma_p`` stands for
the spread of a region of pixels of several noises). So a region that clears the boundary by less than twice ``Z`` and
whose ``z_mixture`` reaches ``Z`` is also judged in a window around each pixel (same low order; the mean of ``u``,
clipped, in the region's standard errors; a window big enough that a right order's mean lies ``2 Z`` standard errors
from the boundary, sized by the region's noise, the quadratic mean of its pixels' ``sigma_p``, at most 31 x 31 pixels,
:data:`MAX_WINDOW_RADIUS`): ``z_local``. A region of one surface whose spread its noise explains is decided as a whole
(windows sized by the scan's noise in a dim region, whose noise is twice the scan's, would hold a right order's mean at
``Z`` standard errors: half its pixels dropped; on the unseen scene seed 1300 at 12 steps, 2 sigma, such windows took
2000 right pixels of one scan). Where even the scan's noise needs a window above 31 x 31 pixels (64 / 10.9 at a residual
noise above 0.057 rad, e.g. 3 steps at the paper's 2 sigma on a dim scene) no window resolves the twin and the region
decides alone: a mixed region can then keep its confidence (a known limit). :func:`twin_ambiguous` marks the pixels
where, for some reachable twin, neither the pixel (``z_pixel``) nor its region (``z_region``, and ``z_local`` where
asked) reaches ``Z`` (default :data:`DEFAULT_SIGNIFICANCE` = 4 standard errors, the significance of
:mod:`dptpu.fpp.region_consistency`: a pixel decision wrong with probability 3e-5): their callers give them no
confidence. No length, focal length or noise level is set: the frequencies, the scan's own residuals and the
significance.

``sigma``: the scan's ``1.4826 median |eps|`` (never below
:data:`dptpu.fpp.frequency_consistency.MIN_SIGMA_RAD`); with the modulation ``B`` of each pixel, scaled as the
phase noise of Eq. (2) scales, ``sqrt(2 / N) sigma_I / B``: ``sigma_p = sigma * median(B) / B_p``.

:func:`near_twin_warning`: the one-line warning of ``dptpu unwrap --method nt`` and the unwrap node when the pair has
a twin within the noise's reach (docs/nodes.md, "NT near-twins", says how to choose a pair without one).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .frequency_consistency import MAD_TO_SIGMA, MIN_SIGMA_RAD, consistency_residual
from .region_consistency import DEFAULT_SIGNIFICANCE, MIN_TEST_PIXELS

__all__ = ["DEFAULT_SIGNIFICANCE", "MAX_WINDOW_RADIUS", "NearTwin", "near_twin_warning", "near_twins",
           "reachable_twins", "residual_noise", "scan_twin_warning", "twin_ambiguous"]

#: sqrt(pi / 2): the standard error of the median of n normal samples is this times sigma / sqrt(n).
_MEDIAN_SE = math.sqrt(math.pi / 2.0)
#: The interquartile range of a normal distribution over its standard deviation.
_IQR_TO_SIGMA = 1.349
#: The standard error of the interquartile range over 1.349 of n normal samples is this times sigma / sqrt(n).
_IQR_SE = 1.166
#: A region whose margin is below this many times the significance is also tested locally (:func:`_local_margin`).
_LOCAL_BELOW = 2.0
#: The twins within reach are judged against this percentile of the pixels' noise (the noisiest pixels beyond it
#: are the per-pixel agreement's, :func:`dptpu.fpp.frequency_consistency.frequency_consistency`).
_REACH_PERCENTILE = 90.0
#: Largest half-width of the window of the local test (:func:`_local_margin`), pixels.
MAX_WINDOW_RADIUS = 15


@dataclass(frozen=True)
class NearTwin:
    """One twin of an NT pair (module docstring).

    Attributes
    ----------
    high_offset : int
        ``m`` > 0: the twin's high order is ``k_h + m`` (and, seen from the twin, ``-m``).
    low_offset : int
        ``n = Round(f_l m / f_h)``: its low order is ``k_l + n``.
    separation_rad : float
        ``s_m = 2 pi (f_l m / f_h - n)``, signed, radians of the low phase.
    share : float
        ``1 - m / f_h``: the share of the projector whose columns ``x`` have the twin at ``x + m W / f_h`` (the first
        ``share`` of it; the last ``share`` has it at ``x - m W / f_h``).
    """

    high_offset: int
    low_offset: int
    separation_rad: float
    share: float

    @property
    def affected_share(self) -> float:
        """The share of the projector whose columns have this twin on one side or the other: the first and the last
        :attr:`share`, ``min(1, 2 share)``."""
        return min(1.0, 2.0 * self.share)


def near_twins(f_h: float, f_l: float, max_separation_rad: float = math.pi) -> tuple[NearTwin, ...]:
    """The twins of the pair ``f_h / f_l`` with ``|s_m| <= max_separation_rad``, nearest first.

    Parameters
    ----------
    f_h, f_l : float
        Periods across the projector, ``f_h > f_l > 0``.
    max_separation_rad : float
        Largest ``|s_m|`` listed, radians.
    """
    if not (math.isfinite(f_h) and math.isfinite(f_l) and f_h > f_l > 0):
        raise ValueError(f"NT frequencies must satisfy f_h > f_l > 0; got f_h = {f_h!r}, f_l = {f_l!r}")
    m = np.arange(1, math.ceil(f_h))  # (M,) every high offset that fits on the projector
    turns = f_l * m / f_h
    n = np.rint(turns)
    separation = 2.0 * np.pi * (turns - n)
    keep = np.abs(separation) <= max_separation_rad
    order = np.argsort(np.abs(separation[keep]), kind="stable")
    return tuple(NearTwin(int(a), int(b), float(s), float(1.0 - a / f_h))
                 for a, b, s in zip(m[keep][order], n[keep][order], separation[keep][order]))


def reachable_twins(f_h: float, f_l: float, noise_rad: float,
                    significance: float = DEFAULT_SIGNIFICANCE) -> tuple[NearTwin, ...]:
    """The twins whose decision boundary (``|s_m| / 2``) lies within ``significance`` times ``noise_rad``, the standard
    deviation of the low-phase residual: the ones noise can reach, nearest first."""
    if not (noise_rad >= 0 and significance > 0):
        raise ValueError(f"noise_rad must be >= 0 and significance > 0; got {noise_rad}, {significance}")
    return near_twins(f_h, f_l, max_separation_rad=min(math.pi, 2.0 * significance * noise_rad))


def residual_noise(residual: np.ndarray, valid: np.ndarray) -> float:
    """The scan's standard deviation of the low-phase residual ``eps``: ``1.4826 median |eps|`` over ``valid``, never
    below :data:`dptpu.fpp.frequency_consistency.MIN_SIGMA_RAD` (that floor where nothing is valid)."""
    values = np.abs(np.asarray(residual)[np.asarray(valid, dtype=bool)])
    values = values[np.isfinite(values)]
    if values.size == 0:
        return MIN_SIGMA_RAD
    return max(MAD_TO_SIGMA * float(np.median(values)), MIN_SIGMA_RAD)


def twin_ambiguous(absolute_high: np.ndarray, wrapped_low: np.ndarray, f_h: float, f_l: float, valid: np.ndarray, *,
                   modulation: np.ndarray | None = None,
                   significance: float = DEFAULT_SIGNIFICANCE) -> np.ndarray:
    """Pixels ``(H, W)`` bool whose published order neither they nor their region tell from a reachable twin.

    For every twin within reach of the scan's noise (:func:`reachable_twins`, both signs of ``m``), at the valid pixels
    whose twin lies on the projector (``0 <= x + m / f_h < 1``, ``x = Phi_h / (2 pi f_h)``): ambiguous where ``z_pixel``
    is below ``significance`` and so is ``z_region`` (or, for a region below twice it whose ``z_mixture`` reaches it,
    ``z_local``; module docstring). Regions: 8-connected pixels of one low order of the published phase,
    ``floor((f_l / f_h) Phi_h / 2 pi)``; one of fewer than :data:`dptpu.fpp.region_consistency.MIN_TEST_PIXELS`
    pixels (where the twin is on the projector) gives no region evidence.

    Parameters
    ----------
    absolute_high : ndarray (H, W)
        The published absolute phase of ``f_h``, radians.
    wrapped_low : ndarray (H, W)
        The wrapped phase of ``f_l``, radians.
    f_h, f_l : float
        The NT pair (none ambiguous unless ``f_h > f_l``: the order is the higher frequency's).
    valid : ndarray (H, W) bool
    modulation : ndarray (H, W), optional
        ``B`` of each pixel: scales the pixel's noise (module docstring); default the scan's noise everywhere.
    significance : float
        ``Z``, standard errors (> 0).
    """
    if not significance > 0:
        raise ValueError(f"significance must be > 0; got {significance}")
    absolute_high = np.asarray(absolute_high, dtype=np.float64)
    eps = consistency_residual(absolute_high, wrapped_low, f_h, f_l)  # (H, W) radians
    valid = np.asarray(valid, dtype=bool) & np.isfinite(eps)
    ambiguous = np.zeros(eps.shape, bool)
    if not valid.any() or not f_h > f_l:  # twins are listed for the higher frequency's order
        return ambiguous
    sigma_scan = residual_noise(eps, valid)
    sigma = _pixel_noise(sigma_scan, modulation, valid)
    twins = reachable_twins(f_h, f_l, float(np.percentile(sigma[valid], _REACH_PERCENTILE)), significance)
    if not twins:
        return ambiguous
    # the low order of the published absolute phase, floor(Phi_l / 2 pi) with Phi_l = (f_l / f_h) Phi_h: smooth where
    # Phi_h is, so its regions end on clean lines (the measured psi_l would flip pixels across its wrap)
    low_order = np.floor((f_l / f_h) * np.where(valid, absolute_high, 0.0) / (2.0 * np.pi)).astype(np.int64)
    labels, count = _low_order_regions(low_order, valid)
    x = np.where(valid, absolute_high / (2.0 * np.pi * f_h), np.nan)  # projector column over W, (H, W)
    # each region's noise from its pixels' modulation (the quadratic mean of sigma_p, the noise of a mean of its
    # pixels), never below the scan's: it sizes the local window; unlike the spread of u, a mixture does not widen it
    region_n = np.bincount(labels[valid], minlength=count)
    region_noise = np.sqrt(np.bincount(labels[valid], np.minimum(sigma[valid], np.pi) ** 2, minlength=count)
                           / np.maximum(region_n, 1))
    region_noise = np.maximum(region_noise, sigma_scan)
    # and the median of sigma_p: the spread of u a region of one surface shows (a mixture shows more)
    by_noise = np.flatnonzero(valid)
    by_noise = by_noise[np.lexsort((sigma.ravel()[by_noise], labels.ravel()[by_noise]))]
    typical_noise = _sorted_median_and_spread(sigma.ravel()[by_noise], labels.ravel()[by_noise], count)[1]
    order = np.flatnonzero(valid)
    order = order[np.lexsort((eps.ravel()[order], labels.ravel()[order]))]  # sorted once by (region, eps)
    sorted_eps, sorted_labels = eps.ravel()[order], labels.ravel()[order]
    for twin in twins:
        for m, s in ((twin.high_offset, twin.separation_rad), (-twin.high_offset, -twin.separation_rad)):
            with np.errstate(invalid="ignore"):
                on_projector = valid & (x + m / f_h >= 0.0) & (x + m / f_h < 1.0)
            if not on_projector.any():
                continue
            u = math.copysign(1.0, s) * eps  # toward the twin: negative
            half = 0.5 * abs(s)
            z_pixel = (u + half) / sigma
            chosen = on_projector.ravel()[order]  # still sorted by (region, eps)
            n, median, spread = _sorted_median_and_spread(sorted_eps[chosen], sorted_labels[chosen], count)
            median = math.copysign(1.0, s) * median  # of u
            sigma_region = np.maximum(spread, sigma_scan)  # (count,) robust standard deviation of u
            with np.errstate(divide="ignore", invalid="ignore"):
                z_region = (median + half) / (_MEDIAN_SE * sigma_region / np.sqrt(n))
            z_region = np.where(n >= MIN_TEST_PIXELS, z_region, -np.inf)
            z_region[0] = -np.inf  # off the regions
            told = (z_pixel >= significance) | (z_region[labels] >= significance)
            # a region that clears the boundary by less than twice the significance and whose spread its pixels'
            # noise does not explain: also locally (a mixture)
            with np.errstate(divide="ignore", invalid="ignore"):
                z_mixture = (spread / typical_noise - 1.0) * np.sqrt(n) / _IQR_SE
            mixed = ~(z_mixture < significance)  # NaN (no noise known) counts as mixed
            check = (on_projector & told & (z_pixel < significance) & (z_region[labels] < _LOCAL_BELOW * significance)
                     & mixed[labels])
            if check.any() and _local_radii(half, np.array([sigma_scan]), significance)[0] > 0:
                # each region's window sized by its own noise, at most MAX_WINDOW_RADIUS
                radius = np.minimum(_local_radii(half, region_noise, significance, limit=False),
                                    MAX_WINDOW_RADIUS)[labels]
                z_local = np.full(eps.shape, np.inf)
                for r in np.unique(radius[check & (radius > 0)]):
                    at = check & (radius == r)
                    z_local[at] = _local_margin(u, half, on_projector, low_order, int(r), sigma_region[labels],
                                                sigma_scan, at)[at]
                told &= ~check | (z_local >= significance)
            ambiguous |= on_projector & ~told
    return ambiguous


def _local_radii(half: float, sigma: np.ndarray, significance: float, *, limit: bool = True) -> np.ndarray:
    """Half-width ``(count,)`` int of the window of :func:`_local_margin` for regions of noise ``sigma`` ``(count,)``
    (standard deviations of ``u``): the one whose mean of a right order lies ``2 Z`` of the region's standard errors
    from the boundary ``|s| / 2``, ``n = (2 Z sigma / (|s| / 2))^2`` pixels (at least 2). Where that exceeds
    :data:`MAX_WINDOW_RADIUS`: 0 (no window that small resolves the twin: the region decides alone), or the radius
    needed with ``limit=False``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        side = 2.0 * significance * np.asarray(sigma, np.float64) / half  # sqrt(n): the window's side, pixels
        radius = np.maximum(2, np.ceil((side - 1.0) / 2.0))
    return np.where(np.isfinite(radius) & (radius <= (MAX_WINDOW_RADIUS if limit else np.inf)), radius,
                    0).astype(np.int64)


def _local_margin(u: np.ndarray, half: float, on_projector: np.ndarray, low_order: np.ndarray, radius: int,
                  sigma: np.ndarray, sigma_scan: float, where: np.ndarray) -> np.ndarray:
    """``z_local`` ``(H, W)`` float64 (module docstring) at ``where`` (at least; -inf off its low orders): the margin
    ``mean(u) + |s| / 2`` of the window of half-width ``radius`` around each pixel over its pixels of the same low
    order (twin on the projector), in standard errors ``sigma / sqrt(n)`` (``sigma`` (H, W): the spread of the
    pixel's region); ``u`` clipped to ``+-(|s| + 3 sigma_scan)`` (one wrong order of another kind moves the mean by a
    bounded step)."""
    size = (2 * radius + 1, 2 * radius + 1)
    bound = 2.0 * half + 3.0 * sigma_scan
    clipped = np.clip(np.nan_to_num(u), -bound, bound).astype(np.float32)
    z_local = np.full(u.shape, -np.inf)
    for value in np.unique(low_order[where & on_projector]):
        mask = on_projector & (low_order == value)
        total = cv2.boxFilter(np.where(mask, clipped, np.float32(0.0)), -1, size, normalize=False,
                              borderType=cv2.BORDER_CONSTANT)
        count = cv2.boxFilter(mask.astype(np.float32), -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
        mean = total[mask] / np.maximum(count[mask], 1.0)
        z_local[mask] = (mean + half) * np.sqrt(count[mask]) / sigma[mask]
    return z_local


def _sorted_median_and_spread(values: np.ndarray, labels: np.ndarray,
                              count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per label ``0..count-1`` of ``values`` sorted by (label, value): ``(n, median, robust standard deviation)``,
    each ``(count,)`` (0 for an empty label); the spread is the interquartile range over 1.349 (a normal's)."""
    n = np.bincount(labels, minlength=count)
    if values.size == 0:
        return n, np.zeros(count), np.zeros(count)
    start = np.concatenate(([0], np.cumsum(n)[:-1]))
    present = n > 0

    def quantile(q: float) -> np.ndarray:
        position = start + q * np.maximum(n - 1, 0)
        low = np.where(present, np.floor(position), 0).astype(np.int64)
        high = np.where(present, np.ceil(position), 0).astype(np.int64)
        weight = position - np.floor(position)
        return np.where(present, values[low] * (1.0 - weight) + values[high] * weight, 0.0)

    return n, quantile(0.5), (quantile(0.75) - quantile(0.25)) / _IQR_TO_SIGMA


def _pixel_noise(sigma_scan: float, modulation: np.ndarray | None, valid: np.ndarray) -> np.ndarray:
    """Each pixel's standard deviation of ``eps`` (module docstring), ``(H, W)`` float64 (the scan's without
    ``modulation``; infinite where ``B`` is not positive)."""
    if modulation is None:
        return np.full(valid.shape, sigma_scan)
    b = np.asarray(modulation, dtype=np.float64)
    typical = float(np.median(b[valid]))
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = np.where(b > 0, sigma_scan * typical / b, np.inf)
    return np.maximum(sigma, MIN_SIGMA_RAD) if typical > 0 else np.full(valid.shape, sigma_scan)


def _low_order_regions(low_order: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, int]:
    """Labels ``(H, W)`` int32 of the 8-connected regions of one low order among ``valid`` (0 off them) and their
    count (with 0); one connected-components pass per low order present (a few)."""
    labels = np.zeros(low_order.shape, np.int32)
    count = 1
    for value in np.unique(low_order[valid]):
        found, components = cv2.connectedComponents((valid & (low_order == value)).astype(np.uint8), connectivity=8,
                                                    ltype=cv2.CV_32S)
        inside = components > 0
        labels[inside] = components[inside] + (count - 1)
        count += found - 1
    return labels, count


def near_twin_warning(f_h: float, f_l: float, noise_rad: float,
                      significance: float = DEFAULT_SIGNIFICANCE) -> str | None:
    """One line naming the pair's nearest twin when noise of ``noise_rad`` (the low-phase residual's standard
    deviation) can reach it (:func:`reachable_twins`), else None."""
    twins = reachable_twins(f_h, f_l, noise_rad, significance)
    if not twins:
        return None
    twin = twins[0]
    where = (f"the first and the last {100.0 * twin.share:.1f} %" if twin.affected_share < 1.0
             else f"all ({100.0 * twin.share:.1f} % from each end)")
    return (f"NT pair {f_h:g} / {f_l:g} has a near-twin {twin.high_offset} high orders ({twin.low_offset} low) away, "
            f"low phases {abs(twin.separation_rad):.3f} rad apart, over {where} of the projector: within reach of "
            f"this scan's phase noise ({noise_rad:.3f} rad; {len(twins)} twin(s) within {significance:g} sigma), so "
            "only regions that tell the twins apart keep their confidence there (docs/nodes.md 'NT near-twins': "
            "choosing a pair without one)")


def scan_twin_warning(absolute_high: np.ndarray, wrapped_low: np.ndarray, f_h: float, f_l: float,
                      valid: np.ndarray) -> str | None:
    """:func:`near_twin_warning` with the noise of a scan: the robust standard deviation of its published order's
    low-phase residual (:func:`residual_noise`); None where no pixel is valid or no twin is within reach."""
    valid = np.asarray(valid, dtype=bool)
    if not valid.any() or not f_h > f_l:
        return None
    eps = consistency_residual(np.where(valid, absolute_high, 0.0), np.where(valid, wrapped_low, 0.0), f_h, f_l)
    return near_twin_warning(f_h, f_l, residual_noise(eps, valid))
