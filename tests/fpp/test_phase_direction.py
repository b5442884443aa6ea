"""The sense of the absolute phase against the rig: a wrong phase_shift_sign (mirrored phase) is caught on rigs
the project was not built on (random focal lengths, baselines, toe-in, either side), a right one is not."""

from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.phase_direction import phase_direction_vote
from dptpu.fpp.tpu import unwrap_mf
from dptpu.sim.outside_rigs import SIGMA_2, issue16_rig, random_outside_rig, render_phases, spheres_and_plane
from dptpu.sim.raycast import trace

RIGS = [pytest.param(lambda: issue16_rig(), id="issue16"),
        *(pytest.param(lambda seed=seed: random_outside_rig(seed), id=f"random{seed}") for seed in range(3))]


@pytest.mark.parametrize("make_rig", RIGS)
def test_mirrored_phase_contradicts_the_rig_and_the_right_one_agrees(make_rig):
    rig = make_rig()
    captured = render_phases(rig, spheres_and_plane(rig, 3), [16.0, 1.0], steps=3, noise_dn=SIGMA_2,
                             supersample=1, seed=1)
    for sign, agrees in ((1, True), (-1, False)):  # -1: the frames decoded with the wrong phase_shift_sign
        psi_h, psi_l = (np.mod(sign * captured.phases[f], 2 * np.pi) for f in (16.0, 1.0))
        unwrapped = unwrap_mf(psi_h, psi_l, 16.0, 1.0)
        orders_right = np.mean(np.floor(unwrapped.absolute_phase / (2 * np.pi))[captured.valid]
                               == captured.order(16.0)[captured.valid])
        vote = phase_direction_vote(unwrapped.absolute_phase, captured.valid, rig, "x")
        assert vote.pairs > 5000
        if agrees:  # MF recovers the orders and the vote is for the rig's sense
            assert orders_right > 0.95 and vote.agreement > 0.95 and not vote.contradicts
        else:  # the mirrored phase unwraps just as smoothly, to wrong orders: only its sense gives it away
            assert orders_right < 0.05 and vote.agreement < 0.05 and vote.contradicts


@pytest.mark.parametrize("axis", ["x", "y"])
def test_ground_truth_phase_votes_with_the_rig_along_either_axis(axis):
    """Horizontal fringes (fringe_axis y) vote along the camera's columns, vertical ones along its rows."""
    rig = random_outside_rig(5)
    hits = trace(rig, spheres_and_plane(rig, 5).meshes)
    coordinate = hits.projector_xy[..., 0 if axis == "x" else 1]  # (H, W) projector pixels
    extent = rig.projector.size[0 if axis == "x" else 1]
    phase = np.where(hits.lit, 2 * np.pi * coordinate / extent, np.nan)
    vote = phase_direction_vote(phase, hits.lit, rig, axis)
    assert vote.agreement > 0.99 and vote.pairs > 5000
    mirrored = phase_direction_vote(2 * np.pi - phase, hits.lit, rig, axis)
    assert mirrored.agreement < 0.01 and mirrored.contradicts


def test_noise_alone_does_not_contradict():
    rig = issue16_rig()
    rng = np.random.default_rng(0)
    height, width = rig.camera.size[1], rig.camera.size[0]
    vote = phase_direction_vote(rng.uniform(0, 2 * np.pi, (height, width)), np.ones((height, width), bool), rig, "x")
    assert 0.4 < vote.agreement < 0.6 and not vote.contradicts
    with pytest.raises(ValueError, match=r"the rig's camera is 120x90; the phase is 10x10"):
        phase_direction_vote(np.zeros((10, 10)), np.ones((10, 10), bool), rig, "x")
