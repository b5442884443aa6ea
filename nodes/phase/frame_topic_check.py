"""Whether the phase node's frames can come at all: a camera side on the frame topic it takes (issue 20).

The phase node takes its frames from one of two topics, by its read-only ``frame_bursts``: FringeFrames on
``/camera/image_raw`` or FringeBursts on ``/camera/frame_bursts``. A camera side (the sim node, the camera node)
given the other setting publishes on the other topic only, and scans then go missing without a word: the scan
monitor reports them lost, the phase node sees nothing. :class:`FrameTopicCheck` tells that apart from an idle
camera: no publisher on the taken topic while the other one has some, seen on two checks in a row (a publisher's
announcement may come a moment after the other's), said once until it changes. Pure logic, the publishers passed in.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FrameTopicCheck"]


@dataclass
class FrameTopicCheck:
    """The warning for frames published on the other frame topic than the one taken (module docstring).

    Parameters
    ----------
    taken : str
        The topic the node takes its frames from (resolved, e.g. ``/camera/frame_bursts``).
    other : str
        The frame topic of the other ``frame_bursts`` setting (resolved, e.g. ``/camera/image_raw``).
    frame_bursts : bool
        The node's ``frame_bursts`` (whether ``taken`` carries FringeBursts).
    """

    taken: str
    other: str
    frame_bursts: bool
    _seen: tuple[str, ...] = ()  # the other topic's publishers found by the last check (no publisher on taken)
    _said: tuple[str, ...] = ()  # those named by the last warning

    def check(self, taken_publishers: list[str], other_publishers: list[str]) -> str | None:
        """The warning to log now, or None: ``*_publishers`` are the node names publishing on each topic."""
        found = tuple(sorted(set(other_publishers))) if not taken_publishers else ()
        seen_before, self._seen = self._seen, found
        if not found:
            self._said = ()
            return None
        if found != seen_before or found == self._said:
            return None  # not twice in a row yet, or said already
        self._said = found
        kind, other_kind = ("FringeBursts", "FringeFrames") if self.frame_bursts else ("FringeFrames", "FringeBursts")
        mine = "true" if self.frame_bursts else "false"
        theirs = "false" if self.frame_bursts else "true"
        return (f"no frame can come: nothing publishes {self.taken}, where this node takes {kind} (frame_bursts:="
                f"{mine}), while {', '.join(found)} publish{'es' if len(found) == 1 else ''} {other_kind} on "
                f"{self.other}; give this node frame_bursts:={theirs}, or the camera side (sim, camera node) "
                f"frame_bursts:={mine} (a launch file's frame_bursts argument sets both)")
