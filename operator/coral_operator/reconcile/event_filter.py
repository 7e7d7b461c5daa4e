"""Drops watch events that change nothing a pass reads (a Node heartbeat, the echo of the
operator's own write), so that they cost no pass.

kopf's `on.event` does not hand over the previous object, as controller-runtime's update
predicates get it; so the filter keeps a small summary of the last event per object, and forgets
it when the object is deleted. Thread safe.
"""

from __future__ import annotations

import threading
from collections.abc import Hashable
from dataclasses import dataclass, field


@dataclass
class EventFilter:
    """The last summary seen per watched object."""

    _lock: threading.Lock = field(default_factory=threading.Lock)
    _last_seen: dict[Hashable, Hashable] = field(default_factory=dict)

    def changed(self, key: Hashable, summary: Hashable) -> bool:
        """Whether `summary` differs from the one last seen under `key` (and remember it)."""
        with self._lock:
            if self._last_seen.get(key) == summary:
                return False
            self._last_seen[key] = summary
            return True

    def forget(self, key: Hashable) -> None:
        with self._lock:
            self._last_seen.pop(key, None)
