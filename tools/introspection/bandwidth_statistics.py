"""Bandwidth of a topic over a sliding window of messages (``dptpu topic bw``, as ``ros2 topic bw``).

A message's size is its serialized size: the bytes of every frame of the wire message (topic,
msgpack header, raw array frames; ``dptpu.messages.encoder``), without the runtime's 40-byte envelope.
Over the last ``window`` messages received at times ``t_0 <= ... <= t_{n-1}``:

- ``bytes_per_s = sum(sizes) / (now - t_0)``, as ``ros2 topic bw`` computes it;
- message size ``mean``, ``min`` and ``max`` in bytes.

Convention: sizes are bytes; printed units are decimal (1 KB = 1000 B, 1 MB = 10**6 B), one unit for
the whole line chosen from the rate, as ``ros2 topic bw`` does.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["BandwidthStatistics", "BandwidthWindow", "format_bandwidth", "DEFAULT_BANDWIDTH_WINDOW"]

#: Messages kept by default (``ros2 topic bw``'s default window).
DEFAULT_BANDWIDTH_WINDOW = 100


@dataclass(frozen=True)
class BandwidthStatistics:
    """Bandwidth figures of one window.

    Attributes
    ----------
    bytes_per_s : float
        Bytes of the window's messages divided by the seconds since its first one.
    mean_bytes : float
    min_bytes, max_bytes : int
        Message sizes, bytes.
    count : int
        Messages in the window (>= 1).
    """

    bytes_per_s: float
    mean_bytes: float
    min_bytes: int
    max_bytes: int
    count: int

    def to_dict(self) -> dict:
        return {"bytes_per_s": self.bytes_per_s, "mean_bytes": self.mean_bytes, "min_bytes": self.min_bytes,
                "max_bytes": self.max_bytes, "count": self.count}


class BandwidthWindow:
    """The arrival times and sizes of the last ``window`` messages of a topic.

    Parameters
    ----------
    window : int
        Messages kept, >= 1.

    Raises
    ------
    ValueError
        ``window`` is not an int >= 1.
    """

    def __init__(self, window: int = DEFAULT_BANDWIDTH_WINDOW):
        if isinstance(window, bool) or not isinstance(window, int) or window < 1:
            raise ValueError(f"bandwidth window must be an int >= 1 (messages); got {window!r}")
        self.window = window
        self._times_s: deque = deque(maxlen=window)
        self._sizes: deque = deque(maxlen=window)
        self.total_count = 0

    def add(self, arrival_s: float, size_bytes: int) -> None:
        """Record a message of ``size_bytes`` bytes that arrived at ``arrival_s`` (monotonic seconds)."""
        if isinstance(size_bytes, bool) or not isinstance(size_bytes, (int, np.integer)) or size_bytes < 0:
            raise ValueError(f"message size must be an int >= 0 (bytes); got {size_bytes!r}")
        self._times_s.append(float(arrival_s))
        self._sizes.append(int(size_bytes))
        self.total_count += 1

    def __len__(self) -> int:
        return len(self._sizes)

    def statistics(self, now_s: float) -> BandwidthStatistics | None:
        """Figures at time ``now_s`` (same clock as the arrivals), or None when empty or no time passed."""
        if not self._sizes:
            return None
        elapsed_s = float(now_s) - self._times_s[0]
        if elapsed_s <= 0.0:
            return None
        sizes = np.asarray(self._sizes, dtype=np.int64)  # (n,)
        return BandwidthStatistics(bytes_per_s=float(sizes.sum()) / elapsed_s, mean_bytes=float(sizes.mean()),
                                   min_bytes=int(sizes.min()), max_bytes=int(sizes.max()), count=int(sizes.size))


def _unit(bytes_per_s: float) -> tuple[str, float]:
    if bytes_per_s < 1000.0:
        return "B", 1.0
    if bytes_per_s < 1_000_000.0:
        return "KB", 1000.0
    return "MB", 1_000_000.0


def format_bandwidth(stats: BandwidthStatistics) -> str:
    """``ros2 topic bw``'s two lines, e.g. ``1.23MB/s from 25 messages`` then ``\\tMessage size mean: ...``."""
    unit, scale = _unit(stats.bytes_per_s)
    rate, mean, low, high = (value / scale for value in (stats.bytes_per_s, stats.mean_bytes, stats.min_bytes,
                                                        stats.max_bytes))
    return (f"{rate:.2f}{unit}/s from {stats.count} messages\n"
            f"\tMessage size mean: {mean:.2f}{unit} min: {low:.2f}{unit} max: {high:.2f}{unit}")
