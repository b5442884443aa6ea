"""Respawn backoff: the first restart after respawn_delay, then doubling, capped, reset by a stable run."""
from __future__ import annotations

import pytest

from dptpu.tools.launch import RespawnPolicy


def test_delays_double_from_the_base_and_stop_at_the_cap():
    policy = RespawnPolicy(base_delay_s=1.0, max_delay_s=5.0)
    assert [policy.delay_s(attempt) for attempt in range(1, 6)] == [1.0, 2.0, 4.0, 5.0, 5.0]
    assert policy.delay_s(10_000) == 5.0


def test_zero_delay_restarts_at_once_then_backs_off_from_a_tenth_of_a_second():
    policy = RespawnPolicy(base_delay_s=0.0, max_delay_s=30.0)
    assert [policy.delay_s(attempt) for attempt in range(1, 5)] == [0.0, 0.2, 0.4, 0.8]


def test_a_stable_run_resets_the_backoff():
    policy = RespawnPolicy(base_delay_s=1.0, max_delay_s=30.0, stable_after_s=10.0)
    assert policy.next_attempt(3, run_time_s=0.5) == 4
    assert policy.next_attempt(3, run_time_s=12.0) == 1


def test_bad_policies_are_rejected():
    with pytest.raises(ValueError, match="respawn_max_delay must be >= respawn_delay"):
        RespawnPolicy(base_delay_s=2.0, max_delay_s=1.0)
    with pytest.raises(ValueError, match="respawn_delay must be >= 0 seconds; got -1"):
        RespawnPolicy(base_delay_s=-1)
    with pytest.raises(ValueError, match="attempt counts restarts from 1; got 0"):
        RespawnPolicy().delay_s(0)
