"""Values a pass derives from a spec that changes only with its generation, kept so that passes do
not derive them again: building and hashing every pod, or validating a spec against its stored
revision, would be most of a pass's cost. The revision history is read from the API once per
system and process, then kept current by the system's own passes.

Thread safe: the queue's workers use these at once.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from coral_operator.planning.revisions import StoredRevision

HistoryKey = tuple[str, str, str]
"""(namespace, system name, system uid)."""


@dataclass
class DesiredPods:
    """The pods each instance's spec asks for, at the generation they were built for."""

    _lock: threading.Lock = field(default_factory=threading.Lock)
    _built: dict[str, tuple[int | None, list[dict[str, Any]]]] = field(default_factory=dict)

    def get(
        self, uid: str, generation: int | None, build: Callable[[], list[dict[str, Any]]]
    ) -> list[dict[str, Any]]:
        with self._lock:
            cached = self._built.get(uid)
        if cached is not None and cached[0] == generation:
            return cached[1]
        desired = build()
        with self._lock:
            self._built[uid] = (generation, desired)
        return desired

    def forget(self, uid: str) -> None:
        with self._lock:
            self._built.pop(uid, None)


@dataclass
class VettedSpecs:
    """Instances whose spec at a generation matched a stored revision of their system and the
    operator's policy (`planning.provenance`)."""

    _lock: threading.Lock = field(default_factory=threading.Lock)
    _vetted: dict[str, tuple[int | None, str]] = field(default_factory=dict)
    """Instance uid -> (generation, system uid)."""

    def has(self, uid: str, generation: int | None, system_uid: str) -> bool:
        with self._lock:
            return self._vetted.get(uid) == (generation, system_uid)

    def add(self, uid: str, generation: int | None, system_uid: str) -> None:
        with self._lock:
            self._vetted[uid] = (generation, system_uid)

    def forget(self, uid: str) -> None:
        with self._lock:
            self._vetted.pop(uid, None)


@dataclass
class RevisionHistories:
    """Each system's stored revisions, as this process read or wrote them last."""

    _lock: threading.Lock = field(default_factory=threading.Lock)
    _history: dict[HistoryKey, list[StoredRevision]] = field(default_factory=dict)

    def get(self, key: HistoryKey, read: Callable[[], list[StoredRevision]]) -> list[StoredRevision]:
        """The history, read with `read` the first time only."""
        with self._lock:
            cached = self._history.get(key)
        if cached is None:
            cached = read()
            with self._lock:
                self._history[key] = cached
        return list(cached)

    def known(self, key: HistoryKey) -> list[StoredRevision] | None:
        """The history if this process holds it, without reading the API."""
        with self._lock:
            cached = self._history.get(key)
        return None if cached is None else list(cached)

    def remember(self, key: HistoryKey, stored: list[StoredRevision]) -> None:
        """What a system pass stored: the history as it is now."""
        with self._lock:
            self._history[key] = list(stored)

    def offer(self, key: HistoryKey, stored: list[StoredRevision]) -> None:
        """Keep a history an instance pass read, unless a system pass stored one meanwhile (which
        may hold a revision written after that read)."""
        with self._lock:
            self._history.setdefault(key, list(stored))

    def forget(self, key: HistoryKey) -> None:
        with self._lock:
            self._history.pop(key, None)

    def __len__(self) -> int:
        with self._lock:
            return len(self._history)
