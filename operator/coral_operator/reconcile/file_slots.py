"""How many system passes may hold their large files at once, and who waits for a slot.

A pass that finds every slot taken is not kept waiting on its worker: two hundred maximal systems
would hold every worker of the queue, and a small system created meanwhile would wait behind all
of them. It returns, and its key is handed back to the queue when a slot frees, in the order the
keys came. Thread safe: the queue's workers share one.
"""

from __future__ import annotations

import threading
from collections.abc import Hashable
from dataclasses import dataclass, field


@dataclass
class FileSlots:
    free: int
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _waiting: dict[Hashable, None] = field(default_factory=dict, repr=False)
    """Keys waiting for a slot, oldest first (a dict: ordered, and each key once)."""

    def take(self, key: Hashable) -> bool:
        """A slot for the pass of `key`, or False and `key` waits for the next one given back."""
        with self._lock:
            if self.free > 0:
                self.free -= 1
                self._waiting.pop(key, None)
                return True
            self._waiting.setdefault(key, None)
            return False

    def give_back(self) -> Hashable | None:
        """Free a slot; the key that waited longest for one, to be passed again, if any."""
        with self._lock:
            self.free += 1
            if not self._waiting:
                return None
            key = next(iter(self._waiting))
            del self._waiting[key]
            return key
