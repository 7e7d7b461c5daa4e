"""Creates, deletes and rollout moves this process made that the indexes do not show yet.

A pass that runs before the watch caught up must not create or delete the same objects again, nor
move more robots than `maxUnavailable` allows, as Kubernetes' own controllers keep
"expectations". Each expectation ends when the index shows it, or after a bound (the write failed
or was replaced).

Thread safe: the queue's workers use these at once.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from coral_operator.reconcile.unseen_writes import WRITE_EXPECTATION_SECONDS

# A rollout move not seen in the index after this long is forgotten (the write failed or was replaced).
EXPECTATION_SECONDS = 60.0


@dataclass
class WriteExpectations:
    """Objects created or deleted under an owner (an instance's pods, a system's instances)."""

    clock: Callable[[], float] = time.monotonic
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _writes: dict[str, dict[str, tuple[bool, float]]] = field(default_factory=dict)
    """Owner uid -> name -> (created, not deleted; when)."""

    def in_flight(self, owner: str, seen: dict[str, bool]) -> tuple[set[str], set[str]]:
        """(created, deleted) under `owner`, not yet shown so by `seen` (name -> deleting, from the
        index); forgets what landed or is older than WRITE_EXPECTATION_SECONDS."""
        now = self.clock()
        with self._lock:
            writes = self._writes.get(owner, {})
            for name, (created, since) in list(writes.items()):
                landed = name in seen if created else seen.get(name, True)
                if landed or now - since > WRITE_EXPECTATION_SECONDS:
                    del writes[name]
            return (
                {name for name, (created, _) in writes.items() if created},
                {name for name, (created, _) in writes.items() if not created},
            )

    def expect(self, owner: str, created: Sequence[str], deleted: Sequence[str] = ()) -> None:
        now = self.clock()
        with self._lock:
            writes = self._writes.setdefault(owner, {})
            writes.update({name: (True, now) for name in created})
            writes.update({name: (False, now) for name in deleted})

    def forget(self, owner: str) -> None:
        with self._lock:
            self._writes.pop(owner, None)


@dataclass
class MoveExpectations:
    """Rollout moves (robot -> revision) per system, until the index shows each robot there."""

    clock: Callable[[], float] = time.monotonic
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _moves: dict[tuple[str, str], dict[str, tuple[str, float]]] = field(default_factory=dict)

    def pending(self, uid: str, namespace: str, observed: dict[str, str]) -> dict[str, str]:
        """Robot -> revision of moves not yet seen in `observed` (robot -> revision)."""
        now = self.clock()
        with self._lock:
            moves = self._moves.get((namespace, uid), {})
            for robot, (revision, since) in list(moves.items()):
                if observed.get(robot) == revision or now - since > EXPECTATION_SECONDS:
                    del moves[robot]
            return {robot: revision for robot, (revision, _) in moves.items()}

    def expect(self, uid: str, namespace: str, moves: dict[str, str]) -> None:
        now = self.clock()
        with self._lock:
            expected = self._moves.setdefault((namespace, uid), {})
            for robot, revision in moves.items():
                expected[robot] = (revision, now)

    def forget(self, uid: str, namespace: str) -> None:
        with self._lock:
            self._moves.pop((namespace, uid), None)
