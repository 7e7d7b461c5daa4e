"""Reconciles one CoralSystem: observe, plan (pure), apply, then report status from what is seen.

Run by the work queue's workers (`reconcile.controller`). A pass reads the system, its robots and
its instances from the indexes and its source files from the API, asks
`planning.system_pass.plan_system` what to write, writes it through its `kube.writer.Writer` in
order (revision history, ConfigMaps before the instances that name them, instances, stale
ConfigMaps last), and computes status with `status.system_status`, patched only when it changed.
See docs/architecture.md.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field
from datetime import datetime
from functools import partial
from typing import Any

from pydantic import ValidationError

from coral_operator.api import keys
from coral_operator.api.rollout import RolloutStatus
from coral_operator.api.system import MAX_INLINE_BYTES, CoralSystemSpec, SourceSpec
from coral_operator.kube import applying, observing
from coral_operator.planning import (
    budgets,
    configmaps,
    instances,
    naming,
    preflight,
    prepull,
    provenance,
    system_pass,
)
from coral_operator.planning.observed import ObservedInstance, ObservedPod, SystemRecord
from coral_operator.planning.policy import Policy
from coral_operator.reconcile import events
from coral_operator.reconcile.declarations import ImageDeclarations
from coral_operator.reconcile.file_slots import FileSlots
from coral_operator.reconcile.indexes import (
    ALL_ROBOTS,
    config_maps_of_system,
    instance_named,
    instances_of_system,
)
from coral_operator.reconcile.reconciler import Key, Reconciler
from coral_operator.status import system_status, transitions
from coral_operator.status.conditions import Reason
from coral_operator.status.rollout import evaluate_rollout

FILES_AT_ONCE = 4
"""System passes that may hold their large files (read from the API) at the same time."""
# Fields of `status.rollout` that come and go: a merge patch removes one only when sent as null.
_OPTIONAL_ROLLOUT_FIELDS = (keys.ROLLOUT.failure, keys.ROLLOUT.rolled_back, keys.ROLLOUT.canary)


@dataclass(kw_only=True, eq=False)
class SystemReconciler(Reconciler):
    """One level-based pass per CoralSystem key (namespace, name)."""

    policy: Policy
    pool: Executor
    """Carries one pass's instance writes in parallel."""
    wake_instance: Callable[[Key], None] = lambda _key: None
    """Pass the instance of this key at once (a move's answer is in memory)."""
    trim: Callable[[], None] = lambda: None
    """Asks for freed memory to be handed back (`reconcile.trimming`) after a pass that held files."""
    declarations: ImageDeclarations = field(default_factory=ImageDeclarations)
    """What component images declare, read from their registries for preflight."""
    file_slots: FileSlots = field(default_factory=lambda: FileSlots(FILES_AT_ONCE), repr=False)
    """Taken by each pass that holds a system's large files."""

    def reconcile(self, key: Key) -> None:
        records = self.indexes.read("coral_systems", key)
        if not records:
            return
        system: SystemRecord = records[0]
        if not system.files_left_out:
            self._reconcile(key, system)
            return
        # The index keeps no large file (docs/architecture.md, "The operator's memory"): this pass
        # reads them and lets go of them when it ends, and only FILES_AT_ONCE passes hold them at
        # once (a megabyte each, twice over while decoded). A newer version read here is only
        # what the watch is about to bring. A pass that finds no free slot gives its worker back
        # and is passed again when a slot frees (`reconcile.file_slots`).
        if not self.file_slots.take(key):
            return
        try:
            body = self.writer.read_system(*key)
            if body is not None:
                self._reconcile(key, observing.system_record(body, keep_files=True))
        finally:
            waiting = self.file_slots.give_back()
            if waiting is not None:
                self.requeue(waiting, 0.0)
        self.trim()

    def _reconcile(self, key: Key, system: SystemRecord) -> None:
        now = self.clock()
        status = self.memory.statuses.observed(system.uid, system.resource_version, system.status)
        # An instance written by hand that names this system is not one of its robots.
        observed = [
            self._with_own_writes(instance)
            for instance in self.indexes.read("coral_instances", instances_of_system(*key))
            if provenance.is_claimed_by(instance, system.name, system.uid)
        ]
        # Every pass, so that an instance seen once and then gone is no longer counted on its way.
        creating, _ = self.memory.creates.in_flight(
            system.uid, {instance.name: False for instance in observed}
        )
        spec = system_pass.parse_spec(system.spec)
        parsed = isinstance(spec, CoralSystemSpec)
        history_key = (system.namespace, system.name, system.uid)
        read_history = partial(self.writer.read_revisions, *history_key)
        observation = system_pass.SystemObservation(
            system=system,
            spec=spec,
            tree=self._read_source(system, spec.tree, "tree") if isinstance(spec, CoralSystemSpec) else None,
            parameters=self._read_source(system, spec.parameters, "parameters")
            if isinstance(spec, CoralSystemSpec)
            else None,
            robots=self.indexes.read("robot_nodes", ALL_ROBOTS),
            instances=observed,
            stored_revisions=self.memory.histories.get(history_key, read_history) if parsed else [],
            expected=self.memory.moves.pending(
                system.uid, system.namespace, {i.robot: i.revision for i in observed}
            ),
            previous_rollout=self.memory.rollouts.last(system.uid) or _rollout_of(status),
            policy=self.policy,
            now=now,
            neighbours=self._neighbours(system) if parsed else [],
            verdicts=self.memory.verdicts,
            images=self.declarations.read(preflight.images_to_read(spec))
            if isinstance(spec, CoralSystemSpec)
            else preflight.ImageTable(),
            # Only a rollout that pre-pulls reads pods: off, a pass costs what it did before.
            pods=self._pods_of(system.namespace, observed)
            if isinstance(spec, CoralSystemSpec) and spec.rollout.pre_pull is not None
            else None,
        )
        plan = system_pass.plan_system(observation)
        problem = plan.problem or system_pass.config_problem(plan)
        if plan.rollout is not None:
            self._apply_history(system, plan)
            self.memory.rollouts.remember(system.uid, plan.rollout.status)
            self.memory.moves.expect(system.uid, system.namespace, plan.rollout.moves)
            try:
                self._apply_changes(system, plan, creating)
                self._apply_pulls(system, plan.rollout.pulls)
            except applying.NameTaken as error:
                problem = system_status.Problem(Reason.NAME_TAKEN, f"{error}.")
            except Exception as error:
                refused = applying.refusal(error)
                if refused is None:
                    raise
                problem = system_status.Problem(
                    Reason.APPLY_REFUSED, f"The API server refused a write: {refused}"
                )
            if plan.rollout.moves or plan.changes.create:
                for note in plan.preflight_notes:
                    self.post(system.reference, "Normal", "PreflightSkipped", note)
            for event in plan.rollout.events:
                self.post(
                    system.reference, "Warning" if event.warning else "Normal", event.reason, event.message
                )
            if plan.rollout.wake_at is not None:
                # Decide again when the canary hold ends, even if nothing else changes.
                self.requeue(key, max((plan.rollout.wake_at - now).total_seconds(), 0.0) + 0.5)
            if plan.rollout.status.failure is not None:
                problem = system_status.Problem(
                    Reason.HEALTH_GATE_FAILED, plan.rollout.status.failure.message
                )
        self._write_status(system, status, observed, plan, problem, now)

    def _pods_of(self, namespace: str, observed: list[ObservedInstance]) -> dict[str, list[ObservedPod]]:
        return {
            i.name: [pod for pods in self.indexes.read("coral_pods", (namespace, i.name)) for pod in pods]
            for i in observed
        }

    def _apply_pulls(self, system: SystemRecord, pulls: prepull.PullWrites) -> None:
        applying.in_parallel(self.pool, self.writer.create_pod, pulls.create)
        applying.in_parallel(
            self.pool, lambda name: self.writer.delete_pod(system.namespace, name), pulls.delete
        )

    def _neighbours(self, system: SystemRecord) -> list[budgets.Footprint]:
        """The footprints of the namespace's other systems, from the index (their robots: the
        instances they have)."""
        found = []
        for namespace, name in self.indexes.keys("coral_systems"):
            if namespace != system.namespace or name == system.name:
                continue
            for other in self.indexes.read("coral_systems", (namespace, name)):
                robots = self.indexes.count("coral_instances", instances_of_system(namespace, name))
                found.append(
                    budgets.Footprint(other.name, other.created, other.spec_bytes, other.share_bytes, robots)
                )
        return found

    def _move(self, manifest: dict[str, Any]) -> dict[str, Any] | None:
        """Move one instance to a new revision and start its pass at once, from the API server's
        answer: through the watch, each waited seconds at 1000 robots, behind every other event of
        the fleet.

        A created instance is not handed over so: its pass waits for the watch. Its pass creates
        pods it owns, and the Kubernetes garbage collector verifies an owner it has not seen yet
        with a GET of it and one of its own owner, the system. Under a fleet's load its CoralInstance
        watch lags its pod watch, and a 1000-robot deployment that created pods from the answer
        cost the API server up to 990 GETs of each (docs/architecture.md, "What is remembered
        between passes")."""
        named = instance_named(manifest["metadata"]["namespace"], manifest["metadata"]["name"])
        before = next(iter(self.indexes.read("coral_instances", named)), None)
        body = self.writer.update_instance(manifest)
        if body is not None:
            record = observing.instance_record(body, self.memory.specs.share(body))
            self.memory.moved.remember(record, replaced=before.resource_version if before else None)
            self.wake_instance((record.namespace, record.name))
        return body

    def _with_own_writes(self, instance: ObservedInstance) -> ObservedInstance:
        """`instance` with the status this process last wrote on it, if the index does not show
        that write yet: the instance's pass wakes this one as it writes a verdict (a robot Ready
        frees a rollout's budget), which would otherwise wait for the watch to bring it back."""
        unseen = self.memory.statuses.unseen(instance.uid, instance.resource_version)
        return instance if unseen is None else observing.with_operator_status(instance, unseen)

    def _read_source(
        self, system: SystemRecord, source: SourceSpec, field: str
    ) -> system_pass.SourceText | system_status.Problem:
        """(text, filename for messages) of an inline or ConfigMap file, or why it cannot be read."""
        if source.inline is not None:
            return source.inline, f"coralsystem/{system.name} spec.{field}.inline"
        ref = source.config_map_ref
        assert ref is not None  # the model guarantees exactly one of the two
        where = f"spec.{field}.configMapRef"
        try:
            found = self.writer.read_config_map_key(system.namespace, ref.name, ref.key)
        except Exception as error:
            # A name the API server cannot take (one written before the schema had a pattern) or a
            # read it refuses: the same answer next time, so a status, not a retried traceback.
            refused = applying.refusal(error)
            if refused is None:
                raise
            return system_status.Problem(
                Reason.CONFIG_MAP_UNREADABLE, f"{where}: ConfigMap {ref.name!r} could not be read: {refused}"
            )
        refusal = configmaps.source_refusal(where, ref.name, None if found is None else found.labels)
        if refusal is not None:
            return system_status.Problem(Reason.CONFIG_MAP_NOT_A_SOURCE, refusal)
        if found is None or found.text is None:
            return system_status.Problem(
                Reason.CONFIG_MAP_NOT_FOUND,
                f"{where}: ConfigMap {ref.name} has no key {ref.key}.",
            )
        size = len(found.text.encode("utf-8", "surrogatepass"))
        if size > MAX_INLINE_BYTES:
            # The bound of the inline field, so that where a file comes from changes nothing.
            return system_status.Problem(
                Reason.TOO_LARGE,
                f"spec.{field}.configMapRef: configmap/{ref.name}/{ref.key} is {size:,} bytes; "
                f"the limit is {MAX_INLINE_BYTES:,}",
            )
        return found.text, f"configmap/{ref.name}/{ref.key}"

    def _apply_history(self, system: SystemRecord, plan: system_pass.SystemPlan) -> None:
        history = plan.history
        assert history is not None
        if history.create is not None:
            self.writer.create_revision(history.create)
        if history.renumber is not None:
            self.writer.renumber_revision(system.namespace, *history.renumber)
        for name in history.delete:
            self.writer.delete_revision(system.namespace, name)
        self.memory.histories.remember((system.namespace, system.name, system.uid), plan.stored_after)

    def _apply_changes(self, system: SystemRecord, plan: system_pass.SystemPlan, creating: set[str]) -> None:
        changes = plan.changes
        if changes.empty:
            return
        if plan.identity:
            self.writer.apply_rbac(plan.identity)
        # ConfigMaps first: an instance must never point at a file that does not exist yet. Named
        # by content, so one the index holds is already right: no create that would answer 409.
        listed = config_maps_of_system(system.namespace, naming.label_value(system.name))
        existing = [
            name for name, owners in self.indexes.read("revision_config_maps", listed) if system.uid in owners
        ]
        for manifest in plan.config_maps:
            if manifest["metadata"]["name"] not in existing:
                self.writer.create_config_map(manifest)
        self._apply_instances(system, changes, creating)
        for stale in configmaps.plan_config_map_cleanup(existing, plan.in_use):
            self.writer.delete_config_map(system.namespace, stale)

    def _apply_instances(
        self, system: SystemRecord, changes: instances.InstanceChanges, creating: set[str]
    ) -> None:
        """`creating`: instances created by earlier passes that the index does not show yet."""
        # One Event per kind of change and pass, with a count, not one per robot.
        namespace, reference = system.namespace, system.reference
        create = [m for m in changes.create if m["metadata"]["name"] not in creating]
        made = applying.in_parallel(self.pool, self.writer.create_instance, create)
        # Created now or already there (409): either way the watch will show it.
        self.memory.creates.expect(system.uid, [m["metadata"]["name"] for m in create])
        created = [m["metadata"]["name"] for m, new in zip(create, made, strict=True) if new is not None]
        self._announce(reference, "InstancesCreated", created, "Created")
        applying.in_parallel(self.pool, self._move, changes.update)
        if changes.update:
            revision = changes.update[0]["spec"]["revision"]
            updated = [m["metadata"]["name"] for m in changes.update]
            self._announce(reference, "InstancesUpdated", updated, "Moved", f" to revision {revision}")
        applying.in_parallel(
            self.pool, lambda name: self.writer.retire_instance(namespace, name), changes.retire
        )
        self._announce(
            reference, "InstancesRetiring", changes.retire, "Stopping", " in reverse order, their robots left"
        )
        applying.in_parallel(
            self.pool, lambda name: self.writer.delete_instance(namespace, name), changes.delete
        )
        self._announce(reference, "InstancesDeleted", changes.delete, "Deleted", " whose robots left")

    def _announce(
        self, reference: dict[str, Any], reason: str, names: list[str], verb: str, how: str = ""
    ) -> None:
        """One Normal Event for a kind of change to the instances `names`, if any, with their count."""
        if names:
            message = f"{verb} {len(names)} CoralInstances{how}: {events.names(names)}"
            self.post(reference, "Normal", reason, message)

    def _write_status(
        self,
        system: SystemRecord,
        status: dict[str, Any],
        observed: list[ObservedInstance],
        plan: system_pass.SystemPlan,
        problem: system_status.Problem | None,
        now: datetime,
    ) -> None:
        rollout = plan.rollout.status.to_wire() if plan.rollout is not None else None
        if rollout is not None:
            for field in _OPTIONAL_ROLLOUT_FIELDS:
                if field not in rollout and field in (status.get("rollout") or {}):
                    rollout[field] = None
        view = system_status.SystemView(
            matched=plan.matched,
            # Instances stopping because their robot left are no longer part of the system's counts.
            instances=[i for i in observed if not i.spec.get("retiring")],
            # Counts and Ready follow the revision robots are moved to (an earlier one after undo).
            revision=plan.rollout.target if plan.rollout is not None else status.get("revision"),
            problem=problem,
            rollout=evaluate_rollout(plan.rollout.status) if plan.rollout is not None else None,
            rolled_back=system_status.describe_rollback(rollout),
        )
        old_conditions = transitions.written_conditions(status)
        new = system_status.build_system_status(
            view, old_conditions=old_conditions, generation=system.generation, now=now
        )
        if rollout is not None:
            new["rollout"] = rollout
        changes = {key: value for key, value in new.items() if status.get(key) != value}
        if not changes:
            return
        version = self.writer.patch_system_status(system.namespace, system.name, changes)
        if version is None:
            return
        after = {
            key: _without_nulls(value) for key, value in {**status, **changes}.items() if value is not None
        }
        self.memory.statuses.remember(system.uid, version, after, replaced=system.resource_version)
        for kind, reason, message in events.condition_events(old_conditions, new["conditions"]):
            self.post(system.reference, kind, reason, message)


def _rollout_of(status: dict[str, Any]) -> RolloutStatus | None:
    try:
        return RolloutStatus.model_validate(status.get("rollout")) if status.get("rollout") else None
    except ValidationError:
        return None


def _without_nulls(value: Any) -> Any:
    # What a merge patch leaves: a field sent as null is removed, not stored as null.
    if isinstance(value, dict):
        return {key: item for key, item in value.items() if item is not None}
    return value
