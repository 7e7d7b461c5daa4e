"""What the reconcilers must remember between passes: only what they cannot observe (yet).

One `Memory` is made per operator process and handed to both reconcilers; nothing else in the
operator keeps state between passes. Each entry says why it cannot be read from the cluster:

- writes the watch has not delivered yet (the status last written, rollout moves);
- derived values too costly to compute on every pass (the pods an instance's spec asks for,
  the revision history, which is read from the API once per system);
- summaries of the last watch event per object, so that an event that changes nothing a pass
  reads (a Node heartbeat, the echo of the operator's own write) costs no pass. kopf's `on.event`
  does not hand over the previous object, as controller-runtime's update predicates get it;
- tables that keep one copy of what many objects hold (`specs`: the part of CoralInstance specs
  every robot of a revision shares) or what many passes compute (`verdicts`: validation results
  by content hash), each bounded (docs/architecture.md, "The operator's memory").

Everything kept per object is forgotten when the watch reports the object deleted.

Thread safe: the queue's workers and kopf's event loop use it at once.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

from coral_operator.api.rollout import RolloutStatus
from coral_operator.kube.observing import SpecTable
from coral_operator.planning.observed import InstanceRecord, ObservedPod
from coral_operator.planning.revisions import StoredRevision
from coral_operator.planning.validation import Verdicts

# A rollout move not seen in the index after this long is forgotten (the write failed or was replaced).
EXPECTATION_SECONDS = 60.0
# A pod or CoralInstance written but not seen after this long is written again: the cost of a
# late watch is one request that answers 409, while an object deleted before the index ever saw it
# must come back.
WRITE_EXPECTATION_SECONDS = 15.0


@dataclass
class Memory:
    """The operator's only state between passes (see the module docstring)."""

    clock: Callable[[], float] = time.monotonic
    specs: SpecTable = field(default_factory=SpecTable)
    verdicts: Verdicts = field(default_factory=Verdicts)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _status_written: dict[str, tuple[str, dict[str, Any], float]] = field(default_factory=dict)
    _status_predating: dict[str, frozenset[str | None]] = field(default_factory=dict)
    """Uid -> the resourceVersions the object had before the last status write (see `status_unseen`)."""
    _deferred_writes: dict[str, int] = field(default_factory=dict)
    _desired_pods: dict[str, tuple[int | None, list[dict[str, Any]]]] = field(default_factory=dict)
    _history: dict[tuple[str, str, str], list[StoredRevision]] = field(default_factory=dict)
    _expected: dict[tuple[str, str], dict[str, tuple[str, float]]] = field(default_factory=dict)
    _rollout_written: dict[str, RolloutStatus] = field(default_factory=dict)
    _last_seen: dict[Hashable, Hashable] = field(default_factory=dict)
    _writes: dict[str, dict[str, tuple[bool, float]]] = field(default_factory=dict)
    """Owner uid -> name -> (created, not deleted; when): an instance's pods, a system's instances."""
    _generation_seen: dict[str, tuple[int | None, float]] = field(default_factory=dict)
    _records_written: dict[tuple[str, str], tuple[InstanceRecord, float, frozenset[str | None]]] = field(
        default_factory=dict
    )
    """(namespace, name) -> (the instance as a system pass moved it, when, the resourceVersions it
    had before)."""
    _spec_vetted: dict[str, tuple[int | None, str]] = field(default_factory=dict)
    """Instance uid -> (generation, system uid) whose spec matched a stored revision and the policy."""

    # --- instances ---------------------------------------------------------------------------

    def status_written(self, uid: str) -> tuple[str | None, dict[str, Any], float]:
        """(resourceVersion, operator's status fields, monotonic time) of the last status write."""
        with self._lock:
            return self._status_written.get(uid, (None, {}, float("-inf")))

    def observed_status(
        self, uid: str, resource_version: str | None, status: dict[str, Any]
    ) -> dict[str, Any]:
        """An object's status, with this process's last write if the object (as the index holds it)
        does not include that write yet. Once it does, the object as observed is the truth, so
        whatever else wrote there is overwritten by the next pass."""
        unseen = self.status_unseen(uid, resource_version)
        return status if unseen is None else {**status, **unseen}

    def status_unseen(self, uid: str, resource_version: str | None) -> dict[str, Any] | None:
        """The operator's status fields this process last wrote on the object, if the object at
        `resource_version` does not include that write yet; else None.

        resourceVersions are opaque: they may be compared for equality only (Kubernetes API
        conventions). So the write is missing only while the index holds a version the object had
        before it (the one the writing pass read, and the ones before writes the index has not
        caught up with either); any other version is the write's or a later one, and the object as
        observed is the truth. A version between the pass's read and its write counts as later: the
        cost is one more write, never a status someone else wrote hidden behind this process's own.
        """
        version, written, _ = self.status_written(uid)
        with self._lock:
            predating = self._status_predating.get(uid, frozenset())
        if version is None or resource_version not in predating:
            return None
        return written

    def is_own_write(self, uid: str, resource_version: str | None) -> bool:
        """Whether the object at `resource_version` is exactly what this process's last status
        write made: nothing else has changed it since, so it holds nothing a pass has not seen."""
        version, _, _ = self.status_written(uid)
        return bool(version) and version == resource_version

    def remember_status(
        self,
        uid: str,
        version: str,
        status: dict[str, Any],
        *,
        replaced: str | None = None,
        deferred: bool = False,
    ) -> None:
        """`version`: the object's resourceVersion the write returned; `replaced`: the one the
        writing pass read. `deferred`: the write could wait (progress, not a verdict); such writes
        are counted until the next verdict, so that a long start is reported less and less often."""
        with self._lock:
            last = self._status_written.get(uid)
            self._status_predating[uid] = _predating(
                last[0] if last else None, self._status_predating.get(uid, frozenset()), replaced
            )
            self._status_written[uid] = (version, status, self.clock())
            self._deferred_writes[uid] = self._deferred_writes.get(uid, 0) + 1 if deferred else 0

    def deferred_writes(self, uid: str) -> int:
        """Status writes that could wait, since the last verdict was written."""
        with self._lock:
            return self._deferred_writes.get(uid, 0)

    def generation_seen_at(self, uid: str, generation: int | None) -> float:
        """When this process first saw the instance at `generation` (monotonic): a status it does
        not write at once must still go out within a bound of the spec's change."""
        now = self.clock()
        with self._lock:
            seen = self._generation_seen.get(uid)
            if seen is None or seen[0] != generation:
                seen = self._generation_seen[uid] = (generation, now)
            return seen[1]

    def desired_pods(
        self, uid: str, generation: int | None, build: Callable[[], list[dict[str, Any]]]
    ) -> list[dict[str, Any]]:
        """The pods for this generation of the spec: a spec changes only with its generation, and
        building and hashing every pod on every pass would be the pass's main cost."""
        with self._lock:
            cached = self._desired_pods.get(uid)
        if cached is not None and cached[0] == generation:
            return cached[1]
        desired = build()
        with self._lock:
            self._desired_pods[uid] = (generation, desired)
        return desired

    def spec_vetted(self, uid: str, generation: int | None, system_uid: str) -> bool:
        """Whether the instance's spec at `generation` was found to be its system's (`vet_spec`):
        a spec changes only with its generation, and comparing it with the stored revision costs
        a validation."""
        with self._lock:
            return self._spec_vetted.get(uid) == (generation, system_uid)

    def vet_spec(self, uid: str, generation: int | None, system_uid: str) -> None:
        with self._lock:
            self._spec_vetted[uid] = (generation, system_uid)

    def pods_in_flight(self, uid: str, observed: list[ObservedPod]) -> tuple[set[str], set[str]]:
        """(created, deleted): pods of an instance this process created or deleted that `observed`
        (the index) does not show so yet. A pass that runs before the watch caught up must not
        create or delete them again, as Kubernetes' own controllers keep "expectations"."""
        return self._writes_in_flight(uid, {pod.name: pod.deleting for pod in observed})

    def expect_pods(self, uid: str, created: list[str], deleted: list[str]) -> None:
        self._expect_writes(uid, created, deleted)

    def _writes_in_flight(self, uid: str, seen: dict[str, bool]) -> tuple[set[str], set[str]]:
        """(created, deleted) by this process under owner `uid`, not yet shown so by `seen` (name ->
        deleting, from the index); forgets what landed or is older than WRITE_EXPECTATION_SECONDS."""
        now = self.clock()
        with self._lock:
            writes = self._writes.get(uid, {})
            for name, (created, since) in list(writes.items()):
                landed = name in seen if created else seen.get(name, True)
                if landed or now - since > WRITE_EXPECTATION_SECONDS:
                    del writes[name]
            return (
                {name for name, (created, _) in writes.items() if created},
                {name for name, (created, _) in writes.items() if not created},
            )

    def _expect_writes(self, uid: str, created: list[str], deleted: list[str]) -> None:
        now = self.clock()
        with self._lock:
            writes = self._writes.setdefault(uid, {})
            writes.update({name: (True, now) for name in created})
            writes.update({name: (False, now) for name in deleted})

    def remember_record(self, record: InstanceRecord, *, replaced: str | None = None) -> None:
        """An instance as the API server answered a system pass's update (a move) of it: its own
        pass can start from it before the watch brings it (`latest_record`). Not a create: a new
        instance's pass waits for the watch (`reconcile.systems`, `SystemReconciler._move`).
        `replaced`: the resourceVersion the index held when the pass moved it."""
        key = (record.namespace, record.name)
        with self._lock:
            last = self._records_written.get(key)
            predating = _predating(
                last[0].resource_version if last else None, last[2] if last else frozenset(), replaced
            )
            self._records_written[key] = (record, self.clock(), predating)

    def latest_record(self, key: tuple[str, str], indexed: InstanceRecord | None) -> InstanceRecord | None:
        """The newer of the instance as the index holds it and as this process last wrote it. A
        written one the index has not caught up with counts for WRITE_EXPECTATION_SECONDS at most,
        and only while the index holds the instance (an update answered for an instance deleted
        since must not bring it back)."""
        now = self.clock()
        with self._lock:
            entry = self._records_written.get(key)
            if entry is None:
                return indexed
            written, since, predating = entry
            # Equality only, as in `status_unseen`: any version but one from before the move is the
            # move's or a later one.
            caught_up = indexed is not None and (
                indexed.uid != written.uid or indexed.resource_version not in predating
            )
            if caught_up or now - since > WRITE_EXPECTATION_SECONDS:
                del self._records_written[key]
                return indexed
        return written if indexed is not None else None

    def is_own_record(self, key: tuple[str, str], resource_version: str | None) -> bool:
        """Whether the instance at `resource_version` is what a system pass of this process moved
        (and handed to the instance's pass at once)."""
        with self._lock:
            entry = self._records_written.get(key)
        return entry is not None and entry[0].resource_version == resource_version

    def forget_record(self, key: tuple[str, str]) -> None:
        with self._lock:
            self._records_written.pop(key, None)

    def forget_instance(self, uid: str) -> None:
        with self._lock:
            self._status_written.pop(uid, None)
            self._status_predating.pop(uid, None)
            self._deferred_writes.pop(uid, None)
            self._desired_pods.pop(uid, None)
            self._writes.pop(uid, None)
            self._generation_seen.pop(uid, None)
            self._spec_vetted.pop(uid, None)

    # --- systems -----------------------------------------------------------------------------

    def stored_revisions(
        self, key: tuple[str, str, str], read: Callable[[], list[StoredRevision]]
    ) -> list[StoredRevision]:
        """A system's revision history: read from the API once per system and process."""
        with self._lock:
            cached = self._history.get(key)
        if cached is None:
            cached = read()
            with self._lock:
                self._history[key] = cached
        return list(cached)

    def remember_revisions(self, key: tuple[str, str, str], stored: list[StoredRevision]) -> None:
        with self._lock:
            self._history[key] = list(stored)

    def known_revisions(self, key: tuple[str, str, str]) -> list[StoredRevision] | None:
        """A system's revision history if this process holds it, without reading the API."""
        with self._lock:
            cached = self._history.get(key)
        return None if cached is None else list(cached)

    def offer_revisions(self, key: tuple[str, str, str], stored: list[StoredRevision]) -> None:
        """Keep a history an instance pass read, unless a system pass stored one meanwhile (which
        may hold a revision written after that read)."""
        with self._lock:
            self._history.setdefault(key, list(stored))

    def expected_moves(self, uid: str, namespace: str, observed: dict[str, str]) -> dict[str, str]:
        """Robot -> revision of rollout moves not yet seen in `observed` (robot -> revision), as
        Kubernetes' own controllers keep "expectations": a pass that runs before the index caught up
        must never move more robots than `maxUnavailable` allows."""
        now = self.clock()
        with self._lock:
            moves = self._expected.get((namespace, uid), {})
            for robot, (revision, since) in list(moves.items()):
                if observed.get(robot) == revision or now - since > EXPECTATION_SECONDS:
                    del moves[robot]
            return {robot: revision for robot, (revision, _) in moves.items()}

    def expect_moves(self, uid: str, namespace: str, moves: dict[str, str]) -> None:
        now = self.clock()
        with self._lock:
            expected = self._expected.setdefault((namespace, uid), {})
            for robot, revision in moves.items():
                expected[robot] = (revision, now)

    def instances_in_flight(self, uid: str, observed: set[str]) -> set[str]:
        """CoralInstances of a system this process created that `observed` (the names in the index)
        does not show yet: a pass that runs before the watch caught up must not create them again
        (each such create would only answer 409)."""
        created, _ = self._writes_in_flight(uid, dict.fromkeys(observed, False))
        return created

    def expect_instances(self, uid: str, created: list[str]) -> None:
        self._expect_writes(uid, created, [])

    def rollout_written(self, uid: str) -> RolloutStatus | None:
        """The rollout status last written: a pass may read the system from before that write, and
        the canary clock or a recorded failure must not be lost to that."""
        with self._lock:
            return self._rollout_written.get(uid)

    def remember_rollout(self, uid: str, status: RolloutStatus) -> None:
        with self._lock:
            self._rollout_written[uid] = status

    def forget_system(self, uid: str, namespace: str, name: str) -> None:
        with self._lock:
            self._status_written.pop(uid, None)
            self._status_predating.pop(uid, None)
            self._deferred_writes.pop(uid, None)
            self._history.pop((namespace, name, uid), None)
            self._expected.pop((namespace, uid), None)
            self._rollout_written.pop(uid, None)
            self._writes.pop(uid, None)

    # --- event filtering ---------------------------------------------------------------------

    def changed(self, key: Hashable, summary: Hashable) -> bool:
        """Whether `summary` differs from the one last seen under `key` (and remember it)."""
        with self._lock:
            if self._last_seen.get(key) == summary:
                return False
            self._last_seen[key] = summary
            return True

    def forget_seen(self, key: Hashable) -> None:
        with self._lock:
            self._last_seen.pop(key, None)


def _predating(
    last_written: str | None, last_predating: frozenset[str | None], replaced: str | None
) -> frozenset[str | None]:
    """The resourceVersions an object had before a write that replaced version `replaced`: that
    one, and, when the writing pass read a version from before the last write too (the index had
    caught up with neither), the last write's own and those before it."""
    if last_written is not None and replaced in last_predating:
        return last_predating | {last_written}
    return frozenset({replaced})

