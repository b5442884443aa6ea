"""Per-publisher sequence numbers of one subscription, kept so that no stranger can poison them.

Every published message carries its publisher's 16-byte id and a sequence number in its envelope
(:mod:`dptpu.graph.transport`). A subscription uses them for two things: to count the messages ZeroMQ dropped
in transport (a gap) and to drop the repeats of a TRANSIENT_LOCAL replay it already has. Both read a table
``publisher id -> last sequence number``, and the envelope is written by whoever sends: any participant can
claim another's id with any sequence number. The rules below keep one such message from doing lasting harm.

Rules (``SequenceTracker.accept``):

- **A live message is always delivered.** Over one ZeroMQ pipe a publisher's live messages arrive in order and
  once; a live sequence number at or below the last one is therefore not a repeat but a restart or a foreign
  message. The table follows it (``last = seq``) and the step is logged, nothing is dropped. (Before: one
  forged message with a real publisher's id and sequence 2**62 made the subscription drop every later real
  message of that publisher as "already delivered".)
- **A replay (HISTORY) is a repeat** only within ``REPLAY_WINDOW`` below the last number; one further below is
  a restart and is delivered.
- **A gap** of up to ``MAX_COUNTED_GAP`` messages is counted as lost at once. A larger jump is held
  provisional: counted only when the publisher's next message confirms it (``seq == jump + 1``); when the old
  numbering continues instead, the jump was foreign and is neither counted nor kept.
- **The table is bounded**: at most ``max_publishers`` ids, the least recently heard evicted first (an
  evicted publisher only loses the de-duplication of its next replay), and the runtime forgets a publisher
  when it disconnects from it (``forget``). Before, every new id added an entry for good (+17 MB per 100k).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import NamedTuple

__all__ = ["SequenceTracker", "Verdict", "MAX_COUNTED_GAP", "REPLAY_WINDOW", "MAX_TRACKED_PUBLISHERS"]

#: Largest gap counted as lost without confirmation (ZeroMQ pipes hold at most a few thousand messages, so a
#: real gap beyond this needs a subscriber stalled for minutes; it is still counted once the next message agrees).
MAX_COUNTED_GAP = 1 << 16
#: Replays (HISTORY) this far below the last sequence number are repeats; the publisher's history depth must be
#: smaller (it keeps its last ``depth`` messages).
REPLAY_WINDOW = 1 << 20
#: Publishers whose numbers one subscription keeps at most.
MAX_TRACKED_PUBLISHERS = 256


class Verdict(NamedTuple):
    """What to do with one message: ``deliver`` it or not, ``lost`` messages to count before it, and ``note``,
    a reason to log (empty when the message was in sequence)."""

    deliver: bool
    lost: int
    note: str


class _Numbers:
    __slots__ = ("last", "jump")

    def __init__(self, last: int):
        self.last = last
        self.jump = -1  # a provisional forward jump (its sequence number), or -1


class SequenceTracker:
    """``publisher id -> last sequence number`` of one subscription, bounded; see the module docstring.

    Pure logic (no sockets, no clock): the subscription calls :meth:`accept` for every message with a valid
    envelope and :meth:`forget` when the runtime disconnects from a publisher.
    """

    def __init__(self, max_publishers: int = MAX_TRACKED_PUBLISHERS):
        if max_publishers < 1:
            raise ValueError(f"max_publishers must be >= 1; got {max_publishers}")
        self.max_publishers = max_publishers
        self._numbers: OrderedDict[bytes, _Numbers] = OrderedDict()

    def __len__(self) -> int:
        return len(self._numbers)

    def last(self, gid: bytes) -> int | None:
        """The last accepted sequence number of publisher ``gid``, or None when it is not tracked."""
        numbers = self._numbers.get(gid)
        return None if numbers is None else numbers.last

    def forget(self, gid: bytes) -> None:
        """Drop publisher ``gid`` (the runtime disconnected from it)."""
        self._numbers.pop(gid, None)

    def accept(self, gid: bytes, seq: int, *, history: bool = False) -> Verdict:
        """The verdict on message ``seq`` of publisher ``gid``; ``history``: a TRANSIENT_LOCAL replay."""
        numbers = self._numbers.get(gid)
        if numbers is None:
            self._numbers[gid] = _Numbers(seq)
            if len(self._numbers) > self.max_publishers:
                self._numbers.popitem(last=False)  # the least recently heard
            return Verdict(True, 0, "")
        self._numbers.move_to_end(gid)
        last = numbers.last
        if numbers.jump >= 0:
            jump, numbers.jump = numbers.jump, -1
            if seq == jump + 1:  # the jump was the publisher's own: its messages in between were lost
                numbers.last = seq
                return Verdict(True, jump - last - 1, "")
            if last < seq <= last + MAX_COUNTED_GAP:  # the old numbering goes on: the jump was foreign
                numbers.last = seq
                return Verdict(True, seq - last - 1,
                               f"a message with sequence number {jump} was out of this publisher's sequence "
                               f"({last} then {seq}): foreign or forged, not counted")
        if seq <= last:
            if history and seq > last - REPLAY_WINDOW:
                return Verdict(False, 0, "")  # a replay of what was delivered
            numbers.last = seq
            return Verdict(True, 0, f"sequence number went back from {last} to {seq}: the publisher restarted "
                                    "its numbering or a foreign message used its id")
        gap = seq - last - 1
        if gap <= MAX_COUNTED_GAP:
            numbers.last = seq
            return Verdict(True, gap, "")
        numbers.jump = seq  # provisional: the next message decides
        return Verdict(True, 0, "")
