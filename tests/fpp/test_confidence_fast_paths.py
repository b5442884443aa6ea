"""The DP-TPU confidence's faster paths give the numbers of their former formulas bit for bit: the float32 margins of
:func:`dptpu.fpp.confidence.network_confidence`, the neighbour support's gradient without pads and float32 masks and
its neighbours compared chunk by chunk (:mod:`dptpu.fpp.order_support`), the two frequencies' agreement computed in
place with ``fmod``, its median by ``bracketed_median`` (:mod:`dptpu.fpp.frequency_consistency`), the region test's
checkerboard, clip, median and counts (:mod:`dptpu.fpp.region_consistency`), and the model gate's fringe density
(:func:`dptpu.models.refine.fringe_density`); on outside rigs (distortion, several
focal lengths, baselines and angles) and the graph's shipped rig with its first random scene, with the paper's camera
noise, at 3 and 12 steps."""
from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest

from dptpu.fpp import tpu
from dptpu.fpp.confidence import network_confidence
from dptpu.fpp.frequency_consistency import MAD_TO_SIGMA, MIN_SIGMA_RAD, frequency_consistency
from dptpu.fpp.order_support import neighbour_support, phase_gradient
from dptpu.fpp.region_consistency import _rejected_by_half, consistency_residual, rejected_regions
from dptpu.sim.outside_rigs import SIGMA_2, issue16_rig, random_outside_rig, render_phases, spheres_and_plane
from dptpu.sim.rig import load_twin_rig
from dptpu.sim.scenes.random_scene import random_scene

F_H, F_L = 20.0, 19.0  # MW
SHIPPED_RIG = Path(__file__).resolve().parents[2] / "launch" / "params" / "shipped_rig.yaml"
#: name -> (rig, scene of it): three outside rigs' spheres before a plane, and the graph's shipped rig with its first
#: random scene (the sim node's twin)
RIGS = {"random-3": (lambda: random_outside_rig(3, size=(160, 120)), lambda rig: spheres_and_plane(rig, 2)),
        "random-8": (lambda: random_outside_rig(8, size=(160, 120)), lambda rig: spheres_and_plane(rig, 2)),
        "issue16": (lambda: issue16_rig(size=(160, 120)), lambda rig: spheres_and_plane(rig, 2)),
        "shipped": (lambda: load_twin_rig(SHIPPED_RIG, size=(160, 120)), lambda rig: random_scene(rig, 1))}


@cache
def scan(name: str, steps: int):
    """``(wrapped high float32, classical MW result, true order, wrapped low float32)`` of a noisy capture of rig
    ``name``'s scene."""
    make_rig, make_scene = RIGS[name]
    rig = make_rig()
    capture = render_phases(rig, make_scene(rig), [F_H, F_L], steps=steps, noise_dn=SIGMA_2, seed=7)
    psi_h, psi_l = (capture.phases[f].astype(np.float32) for f in (F_H, F_L))
    valid = capture.valid & (capture.modulation[F_H] > 3.0) & (capture.modulation[F_L] > 3.0)
    result = tpu.unwrap("mw", psi_h, psi_l, F_H, F_L, valid=valid)
    return psi_h, result, capture.order(F_H).astype(np.int32), psi_l


def _gradient_before(wrapped, valid, radius=2):
    """phase_gradient as written before its version without pads and float32 casts of boolean maps."""
    frac = (np.asarray(wrapped, dtype=np.float64) / (2.0 * np.pi)).astype(np.float32)
    size = (2 * radius + 1, 2 * radius + 1)
    gradients = []
    for axis in (0, 1):
        step = np.diff(frac, axis=axis)
        step -= np.rint(step)
        pair = (valid[1:] & valid[:-1]) if axis == 0 else (valid[:, 1:] & valid[:, :-1])
        pad = ((0, 1), (0, 0)) if axis == 0 else ((0, 0), (0, 1))
        total = cv2.boxFilter(np.pad(np.where(pair, step, 0.0), pad).astype(np.float32), -1, size, normalize=False,
                              borderType=cv2.BORDER_CONSTANT)
        count = cv2.boxFilter(np.pad(pair, pad).astype(np.float32), -1, size, normalize=False,
                              borderType=cv2.BORDER_CONSTANT)
        gradients.append(total / np.maximum(count, 1.0))
    return gradients


@pytest.mark.parametrize("name", RIGS)
@pytest.mark.parametrize("steps", [3, 12])
def test_phase_gradient_is_the_former_one(name, steps):
    psi_h, result, _, _ = scan(name, steps)
    wrapped = np.where(result.valid, psi_h, np.float32(0.0))
    for now, before in zip(phase_gradient(wrapped, result.valid), _gradient_before(wrapped, result.valid)):
        assert now.dtype == before.dtype == np.float32 and np.array_equal(now, before)
        assert np.count_nonzero(now) > 0.5 * result.valid.sum()


def _support_loop(order, wrapped, valid, confidence, radius, where):
    """neighbour_support's comparison as written before its chunked, vectorized one: a loop over the window's
    offsets, a running float32 sum from 0 (the gradient and counts are the function's own)."""
    valid = valid & np.isfinite(wrapped)
    psi = np.where(valid, wrapped, 0.0)
    absolute = np.where(valid, order.astype(np.float64) + psi / (2.0 * np.pi), np.nan)
    weight = np.where(valid, np.clip(np.nan_to_num(confidence.astype(np.float64)), 0.0, 1.0), 0.0)
    pixels = np.flatnonzero(valid & where)
    gy, gx = phase_gradient(psi, valid)
    grad_y, grad_x = gy.ravel()[pixels], gx.ravel()[pixels]
    size = (2 * radius + 1, 2 * radius + 1)
    neighbours = cv2.boxFilter(valid.astype(np.float32), -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
    padded_width = valid.shape[1] + 2 * radius
    rows, cols = np.divmod(pixels, valid.shape[1])
    centre = (rows + radius) * padded_width + cols + radius
    padded = np.pad(absolute.astype(np.float32), radius, constant_values=np.nan).ravel()
    padded_weight = np.pad(weight.astype(np.float32), radius).ravel()
    own = absolute.ravel()[pixels].astype(np.float32)
    agreeing = np.zeros(pixels.size, np.float32)
    with np.errstate(invalid="ignore"):
        for dy in range(-radius, radius + 1):
            for dx in range(-radius, radius + 1):
                if dy or dx:
                    shift = centre + (dy * padded_width + dx)
                    difference = padded[shift] - own
                    difference -= grad_y * dy + grad_x * dx
                    agreeing += np.where(np.abs(difference) < 0.25, padded_weight[shift], 0.0)
    support = np.zeros(valid.shape, np.float32)
    support.ravel()[pixels] = agreeing / np.maximum(neighbours.ravel()[pixels] - 1.0, 1.0)
    return support


@pytest.mark.parametrize("name", RIGS)
@pytest.mark.parametrize("radius", [2, 4])
def test_chunked_neighbour_support_is_the_loop(name, radius):
    psi_h, result, _, _ = scan(name, 3)
    where = np.ones(result.valid.shape, bool)  # every valid pixel: several chunks of the comparison
    assert result.valid.sum() > 8192
    wrapped = np.where(result.valid, psi_h, np.float32(np.nan))
    support = neighbour_support(result.fringe_order, wrapped, result.valid, result.reliability, radius=radius)
    assert np.array_equal(support, _support_loop(result.fringe_order, wrapped, result.valid, result.reliability,
                                                 radius, where))
    assert 0.2 < np.mean(support[result.valid]) < 0.95  # classical MW at 3 steps: neither no support nor all


@pytest.mark.parametrize("name", RIGS)
def test_float32_network_confidence_is_the_float64_one(name):
    psi_h, result, truth, _ = scan(name, 3)
    rng = np.random.default_rng(3)
    # a network output near the true order (some pixels near the rounding margin), an order with a few wrong ones
    continuous = (truth + rng.normal(0.0, 0.2, truth.shape)).astype(np.float32)
    continuous[::17, ::13] = truth[::17, ::13] + np.float32(3e-8)  # within 2^-24 of an integer
    order = np.where(result.valid, np.rint(continuous), 0).astype(np.int32)
    prior = np.where(rng.random(truth.shape) < 0.1, result.fringe_order + rng.integers(-2, 3, truth.shape),
                     result.fringe_order).astype(np.int32)
    wrapped = np.where(result.valid, psi_h, np.float32(0.0))
    fast = network_confidence(continuous, order, prior, result.valid, wrapped_high=wrapped)
    reference = network_confidence(continuous.astype(np.float64), order, prior, result.valid, wrapped_high=wrapped)
    assert fast.dtype == reference.dtype == np.float32
    assert np.array_equal(fast, reference)
    # each term at work: the prior's 1/2, the margins and supports between 0 and 1
    assert 0.005 < np.mean(fast[result.valid] == 0.5) and np.mean(((fast > 0) & (fast < 1))[result.valid]) > 0.1


def _consistency_before(absolute_high, wrapped_low, f_h, f_l, valid, floor, scale=6.25):
    """frequency_consistency as written before its in-place version: np.mod, new arrays, np.clip."""
    difference = (f_l / f_h) * np.asarray(absolute_high, np.float64) - np.asarray(wrapped_low, np.float64)
    eps = np.abs(np.pi - np.mod(np.pi - difference, 2.0 * np.pi))
    valid = valid & np.isfinite(eps)
    sigma = max(MAD_TO_SIGMA * float(np.median(eps[valid])), MIN_SIGMA_RAD)
    if floor is not None:
        sigma = np.maximum(sigma, np.where(np.isfinite(floor), np.asarray(floor, np.float64), 0.0))
    with np.errstate(invalid="ignore"):
        confidence = np.clip(1.0 - eps / (scale * sigma), 0.0, 1.0)
    return np.where(valid, confidence, 0.0).astype(np.float32)


@pytest.mark.parametrize("name", RIGS)
@pytest.mark.parametrize("with_floor", [False, True])
def test_in_place_frequency_consistency_is_the_former_one(name, with_floor):
    psi_h, result, truth, _ = scan(name, 3)
    rng = np.random.default_rng(5)
    order = np.where(rng.random(truth.shape) < 0.02, truth + 1, truth)  # some wrong orders: large residuals
    absolute = psi_h.astype(np.float64) + 2 * np.pi * order
    absolute[::7, ::5] = 2 * np.pi * np.round(absolute[::7, ::5] / (2 * np.pi))  # exact multiples: zero remainders
    true_absolute = psi_h.astype(np.float64) + 2 * np.pi * truth
    psi_l = np.where(result.valid, np.float32(1.0), np.float32(np.nan)) * (true_absolute * F_L / F_H % (2 * np.pi))
    psi_l = (psi_l + rng.normal(0.0, 0.02, psi_l.shape)).astype(np.float32)
    floor = None
    if with_floor:
        floor = rng.uniform(0.0, 0.05, truth.shape).astype(np.float32)
        floor[::11, ::3] = np.inf
    fast = frequency_consistency(absolute, psi_l, F_H, F_L, result.valid, floor=floor)
    assert np.array_equal(fast, _consistency_before(absolute, psi_l, F_H, F_L, result.valid, floor))
    assert 0.01 < np.mean((fast > 0) & (fast < 1)) and np.any(fast[result.valid] == 0)  # neither all 0 nor all 1


def _regions_before(absolute_high, wrapped_low, f_h, f_l, valid, radius=3, significance=4.0):
    """rejected_regions as written before its cuts: np.median, np.clip, the checkerboard from index grids, the
    proposing half's count from a float32 copy (the halves' test itself is the function's own)."""
    ratio = f_l / f_h
    r = consistency_residual(absolute_high, wrapped_low, f_h, f_l, dtype=np.float32)
    r *= np.float32(1.0 / (2.0 * np.pi * (ratio - round(ratio))))
    r[~valid] = np.nan
    known = np.isfinite(r)
    scan_sigma = MAD_TO_SIGMA * float(np.median(np.abs(r[known])))
    votes = np.clip(np.where(known, r, np.float32(0.0)), -2.0, 2.0)
    checkerboard = (np.arange(r.shape[0])[:, None] + np.arange(r.shape[1])[None, :]) % 2 == 0
    first_half = known & checkerboard
    rejected = np.zeros(r.shape, bool)
    for proposing, testing in ((first_half, known & ~first_half), (known & ~first_half, first_half)):
        rejected |= _rejected_by_half(r, votes, known, proposing, testing, scan_sigma, radius, significance)
    return rejected


@pytest.mark.parametrize("name", RIGS)
def test_region_test_is_the_former_one(name):
    psi_h, result, truth, psi_l = scan(name, 12)
    valid = result.valid
    order = truth.copy()
    rows, cols = np.nonzero(valid)
    centre = len(rows) // 2
    patch = (np.abs(rows - rows[centre]) < 6) & (np.abs(cols - cols[centre]) < 8)
    order[rows[patch], cols[patch]] += 1  # a patch one order off: the test's case
    absolute = psi_h.astype(np.float64) + 2 * np.pi * order
    rejected = rejected_regions(absolute, psi_l, F_H, F_L, valid)
    assert np.array_equal(rejected, _regions_before(absolute, psi_l, F_H, F_L, valid))
    assert rejected[rows[patch], cols[patch]].mean() > 0.5  # the patch found


def _density_before(wrapped_high, valid):
    """models.refine.fringe_density as written before its in-place version (np.mod, np.median)."""
    psi = np.where(valid, np.asarray(wrapped_high, dtype=np.float64), np.nan)
    medians = []
    for axis in (0, 1):
        steps = np.diff(psi, axis=axis)
        steps = np.abs(np.mod(steps[np.isfinite(steps)] + np.pi, 2.0 * np.pi) - np.pi) / (2.0 * np.pi)
        medians.append(float(np.median(steps)) if steps.size else 0.0)
    return max(medians)


@pytest.mark.parametrize("name", RIGS)
def test_in_place_fringe_density_is_the_former_one(name):
    from dptpu.models.refine import fringe_density  # the model gate of the unwrap node's model:=auto

    psi_h, result, _, psi_l = scan(name, 3)
    tiled = np.tile(psi_h, (4, 4))  # 640x480: more differences than the bracketed median's smallest array
    tiled[::9, ::7] = 0.0  # steps of exactly -psi: remainders of 0 and 2 pi
    for phase, valid in ((psi_h, result.valid), (psi_l, result.valid), (tiled, np.tile(result.valid, (4, 4)))):
        assert fringe_density(phase, valid) == _density_before(phase, valid)
    assert 0.0 < fringe_density(psi_h, result.valid) < 0.5
