"""This process's own writes that the indexes may not show yet.

A watch brings a write back a moment after the API server answered it, seconds later for a fleet.
A pass that runs meanwhile reads the object from before the write; it must neither write the same
thing again nor decide from the older state. resourceVersions are opaque, so they are compared for
equality only (Kubernetes API conventions): a write is missing while the index holds a version the
object had before it, and any other version is the write's or a later one, and is the truth.

Thread safe: the queue's workers and kopf's event loop use these at once.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from coral_operator.api.rollout import RolloutStatus
from coral_operator.planning.observed import InstanceRecord

# A pod or CoralInstance written but not seen after this long is written again: the cost of a
# late watch is one request that answers 409, while an object deleted before the index ever saw it
# must come back.
WRITE_EXPECTATION_SECONDS = 15.0


@dataclass
class StatusWrites:
    """The status each object was last written by this process, until the index shows the write."""

    clock: Callable[[], float] = time.monotonic
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _written: dict[str, tuple[str, dict[str, Any], float]] = field(default_factory=dict)
    """Uid -> (resourceVersion the write returned, the operator's status fields, monotonic time)."""
    _predating: dict[str, frozenset[str | None]] = field(default_factory=dict)
    """Uid -> the resourceVersions the object had before the last status write (see `unseen`)."""

    def last(self, uid: str) -> tuple[str | None, dict[str, Any], float]:
        """(resourceVersion, operator's status fields, monotonic time) of the last status write."""
        with self._lock:
            return self._written.get(uid, (None, {}, float("-inf")))

    def observed(self, uid: str, resource_version: str | None, status: dict[str, Any]) -> dict[str, Any]:
        """An object's status, with this process's last write if the object (as the index holds it)
        does not include that write yet. Once it does, the object as observed is the truth, so
        whatever else wrote there is overwritten by the next pass."""
        unseen = self.unseen(uid, resource_version)
        return status if unseen is None else {**status, **unseen}

    def unseen(self, uid: str, resource_version: str | None) -> dict[str, Any] | None:
        """The operator's status fields this process last wrote on the object, if the object at
        `resource_version` does not include that write yet; else None.

        The write is missing only while the index holds a version the object had before it (the
        one the writing pass read, and the ones before writes the index has not caught up with
        either); any other version is the write's or a later one. A version between the pass's
        read and its write counts as later: the cost is one more write, never a status someone
        else wrote hidden behind this process's own.
        """
        with self._lock:
            written = self._written.get(uid)
            predating = self._predating.get(uid, frozenset())
        if written is None or resource_version not in predating:
            return None
        return written[1]

    def is_own(self, uid: str, resource_version: str | None) -> bool:
        """Whether the object at `resource_version` is exactly what this process's last status
        write made: nothing else has changed it since, so it holds nothing a pass has not seen."""
        version, _, _ = self.last(uid)
        return bool(version) and version == resource_version

    def remember(
        self, uid: str, version: str, status: dict[str, Any], *, replaced: str | None = None
    ) -> None:
        """`version`: the object's resourceVersion the write returned; `replaced`: the one the
        writing pass read."""
        with self._lock:
            last = self._written.get(uid)
            self._predating[uid] = predating(
                last[0] if last else None, self._predating.get(uid, frozenset()), replaced
            )
            self._written[uid] = (version, status, self.clock())

    def forget(self, uid: str) -> None:
        with self._lock:
            self._written.pop(uid, None)
            self._predating.pop(uid, None)


@dataclass
class MovedInstances:
    """Instances as the API server answered a system pass's update (a move) of them, so that the
    instance's own pass can start from the answer before the watch brings it. Not a create: a new
    instance's pass waits for the watch (`reconcile.systems`, `SystemReconciler._move`)."""

    clock: Callable[[], float] = time.monotonic
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _moved: dict[tuple[str, str], tuple[InstanceRecord, float, frozenset[str | None]]] = field(
        default_factory=dict
    )
    """(namespace, name) -> (the instance as moved, when, the resourceVersions it had before)."""

    def remember(self, record: InstanceRecord, *, replaced: str | None = None) -> None:
        """`replaced`: the resourceVersion the index held when the pass moved it."""
        key = (record.namespace, record.name)
        with self._lock:
            last = self._moved.get(key)
            before = predating(
                last[0].resource_version if last else None, last[2] if last else frozenset(), replaced
            )
            self._moved[key] = (record, self.clock(), before)

    def latest(self, key: tuple[str, str], indexed: InstanceRecord | None) -> InstanceRecord | None:
        """The newer of the instance as the index holds it and as this process last moved it. A
        moved one the index has not caught up with counts for WRITE_EXPECTATION_SECONDS at most,
        and only while the index holds the instance (an update answered for an instance deleted
        since must not bring it back)."""
        now = self.clock()
        with self._lock:
            entry = self._moved.get(key)
            if entry is None:
                return indexed
            written, since, before = entry
            # Equality only, as in `StatusWrites.unseen`: any version but one from before the move
            # is the move's or a later one.
            caught_up = indexed is not None and (
                indexed.uid != written.uid or indexed.resource_version not in before
            )
            if caught_up or now - since > WRITE_EXPECTATION_SECONDS:
                del self._moved[key]
                return indexed
        return written if indexed is not None else None

    def is_own(self, key: tuple[str, str], resource_version: str | None) -> bool:
        """Whether the instance at `resource_version` is what a system pass of this process moved
        (and handed to the instance's pass at once)."""
        with self._lock:
            entry = self._moved.get(key)
        return entry is not None and entry[0].resource_version == resource_version

    def forget(self, key: tuple[str, str]) -> None:
        with self._lock:
            self._moved.pop(key, None)


@dataclass
class RolloutWrites:
    """The rollout status last written per system: a pass may read the system from before that
    write, and the canary clock or a recorded failure must not be lost to that."""

    _lock: threading.Lock = field(default_factory=threading.Lock)
    _written: dict[str, RolloutStatus] = field(default_factory=dict)

    def last(self, uid: str) -> RolloutStatus | None:
        with self._lock:
            return self._written.get(uid)

    def remember(self, uid: str, status: RolloutStatus) -> None:
        with self._lock:
            self._written[uid] = status

    def forget(self, uid: str) -> None:
        with self._lock:
            self._written.pop(uid, None)


def predating(
    last_written: str | None, last_predating: frozenset[str | None], replaced: str | None
) -> frozenset[str | None]:
    """The resourceVersions an object had before a write that replaced version `replaced`: that
    one, and, when the writing pass read a version from before the last write too (the index had
    caught up with neither), the last write's own and those before it."""
    if last_written is not None and replaced in last_predating:
        return last_predating | {last_written}
    return frozenset({replaced})
