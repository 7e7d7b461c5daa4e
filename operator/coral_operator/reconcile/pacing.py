"""What the pacing of CoralInstance status writes (`planning.status_pacing`) counts from.

Per instance: how many writes that could wait went out since the last verdict (each such write
waits longer than the one before), and when this process first saw the instance's generation (a
status it does not write at once must still go out within a bound of the spec's change). Thread
safe.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass
class WritePacing:
    """Per instance: writes that could wait since the last verdict, and when its generation was seen."""

    clock: Callable[[], float] = time.monotonic
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _deferred: dict[str, int] = field(default_factory=dict)
    _generation_seen: dict[str, tuple[int | None, float]] = field(default_factory=dict)

    def deferred_writes(self, uid: str) -> int:
        """Status writes that could wait, since the last verdict was written."""
        with self._lock:
            return self._deferred.get(uid, 0)

    def wrote(self, uid: str, *, deferred: bool) -> None:
        """A status write went out; `deferred`: it could have waited (progress, not a verdict)."""
        with self._lock:
            self._deferred[uid] = self._deferred.get(uid, 0) + 1 if deferred else 0

    def generation_seen_at(self, uid: str, generation: int | None) -> float:
        """When this process first saw the instance at `generation` (monotonic)."""
        now = self.clock()
        with self._lock:
            seen = self._generation_seen.get(uid)
            if seen is None or seen[0] != generation:
                seen = self._generation_seen[uid] = (generation, now)
            return seen[1]

    def forget(self, uid: str) -> None:
        with self._lock:
            self._deferred.pop(uid, None)
            self._generation_seen.pop(uid, None)
