"""When to restart a node that exited: ``respawn_delay`` doubled per quick crash, capped.

A node that keeps crashing right after start must not burn a core; a node that ran fine for a while
and then died once should come back quickly. So the delay before restart ``n`` (1-based) of a run of
consecutive quick exits is

    delay_n = min(max_delay_s, max(base_delay_s, 0.1) * 2 ** (n - 1))     (first: exactly base_delay_s)

and a process that stayed up for at least ``stable_after_s`` resets ``n`` to 1.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["RespawnPolicy", "MIN_BACKOFF_BASE_S"]

#: Doubling starts from at least this many seconds, so ``respawn_delay: 0`` still backs off.
MIN_BACKOFF_BASE_S = 0.1


@dataclass(frozen=True)
class RespawnPolicy:
    """Restart delays of one node.

    base_delay_s : the launch file's ``respawn_delay``, seconds >= 0 (delay of the first restart).
    max_delay_s : the launch file's ``respawn_max_delay``, seconds >= base_delay_s (the cap).
    stable_after_s : a run at least this long (seconds > 0) counts as healthy and resets the backoff.
    """

    base_delay_s: float = 0.0
    max_delay_s: float = 30.0
    stable_after_s: float = 10.0

    def __post_init__(self):
        if not self.base_delay_s >= 0:
            raise ValueError(f"respawn_delay must be >= 0 seconds; got {self.base_delay_s}")
        if not self.max_delay_s >= self.base_delay_s:
            raise ValueError(f"respawn_max_delay must be >= respawn_delay ({self.base_delay_s} s); "
                             f"got {self.max_delay_s}")
        if not self.stable_after_s > 0:
            raise ValueError(f"stable_after_s must be > 0 seconds; got {self.stable_after_s}")

    def delay_s(self, attempt: int) -> float:
        """Seconds to wait before restart number ``attempt`` (1-based) of a run of quick exits."""
        if attempt < 1:
            raise ValueError(f"attempt counts restarts from 1; got {attempt}")
        if attempt == 1:
            return self.base_delay_s
        base = max(self.base_delay_s, MIN_BACKOFF_BASE_S)
        return min(self.max_delay_s, base * 2.0 ** min(attempt - 1, 60))

    def next_attempt(self, previous_attempt: int, run_time_s: float) -> int:
        """The attempt number of the coming restart after a run of ``run_time_s`` seconds."""
        return 1 if run_time_s >= self.stable_after_s else previous_attempt + 1
