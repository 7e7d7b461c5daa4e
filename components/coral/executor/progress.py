"""Whether a tree makes progress: one node failing the same way again and again means it does not.

A robot whose skillset came back without its state retried `ProcessScan` about 240,000 times in
ten minutes while its instance read Ready and RUNNING (issue 50). What such a loop has that a
healthy mission lacks is one behavior failing with the same explanation over and over, and never
succeeding in between. Failures without a message are left out: a condition that says no (is a
stop requested? is the data exhausted?) fails on every pass of a healthy loop.

Pure; the tick loop feeds it every node transition with its monotonic and wall clocks.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

# The same failure, whatever the counts and times in its message ("scan 1203 rejected").
_NUMBERS = re.compile(r"\d+(\.\d+)?")
# A single failure, or two, is a retry doing its job; the loop is one that keeps going.
MIN_FAILURES = 3


@dataclass
class _Streak:
    path: str
    node_id: str
    message: str
    shape: str
    first_at: float
    last_at: float
    since: float
    """Wall-clock time of the first failure, for the report."""
    failures: int = 1


def _shape(message: str) -> str:
    return _NUMBERS.sub("#", message)


class ProgressWatch:
    """Tells when one node has failed the same way for `limit_s` without succeeding in between."""

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        self._streak: _Streak | None = None

    def failed(self, path: str, node_id: str, message: str, now: float, wall: float) -> None:
        """A node at `path` returned FAILURE saying `message` (empty: it did not say why)."""
        if not message or self.limit_s <= 0:
            return
        shape, streak = _shape(message), self._streak
        if streak is not None and (streak.path, streak.shape) == (path, shape) and not self._lapsed(now):
            streak.failures += 1
            streak.last_at = now
            return
        self._streak = _Streak(path, node_id, message, shape, now, now, wall)

    def succeeded(self, path: str) -> None:
        """The node at `path` returned SUCCESS: if it was the one failing, the loop ended."""
        if self._streak is not None and self._streak.path == path:
            self._streak = None

    def stuck(self, now: float) -> dict[str, object] | None:
        """The node, its message and since when (wall clock) while the tree makes no progress.

        Stable while the loop lasts (the first message, not the latest), so a report of it changes
        once when the loop starts and once when it ends.
        """
        streak = self._streak
        if streak is None or self._lapsed(now):
            return None
        if streak.failures < MIN_FAILURES or streak.last_at - streak.first_at < self.limit_s:
            return None
        return {
            "path": streak.path,
            "node_id": streak.node_id,
            "message": streak.message,
            "since": streak.since,
        }

    def _lapsed(self, now: float) -> bool:
        """The node has not failed again for as long as a loop must last: the tree moved on."""
        return self._streak is not None and now - self._streak.last_at > self.limit_s
