"""Reconciles one CoralInstance: observe, plan (pure), apply, then report status from what is seen.

Run by the work queue's workers (`reconcile.controller`), never inside a kopf handler. A pass
reads the instance, its pods and its robot's Node from the indexes, asks
`planning.instance_pass.plan_instance` what to write, writes it through its `kube.writer.Writer`,
and computes the status with `status.instance_status`. The status is patched at once only when a
verdict changed; progress alone waits, and so does a status that tells no reader more than the one
written (`planning.status_pacing`).
The executor's fields (`tree`, `plugins`) are read, never written, and read defensively
(`status.executor_report`): a value the operator cannot read is named on the conditions, never a
pass that fails before it writes. Whatever else the executor writes there is overwritten
(`status.ownership`). Pods are built only for an instance its system made for its robot, at one of
the system's stored revisions, within the operator's policy (`planning.provenance`); any other is
left alone, Stalled with the reasons and an Event. See docs/architecture.md.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.kube import applying, observing
from coral_operator.planning import instance_pass, provenance, status_pacing
from coral_operator.planning.observed import InstanceRecord, ObservedPod, RobotNode, SystemRecord
from coral_operator.planning.pods import HostPathRefused, PodSettings
from coral_operator.planning.pull_state import PULL_ROLE
from coral_operator.planning.revisions import StoredRevision
from coral_operator.reconcile import events
from coral_operator.reconcile.indexes import instance_named, instances_of_system
from coral_operator.reconcile.reconciler import Key, Reconciler
from coral_operator.status import executor_report, instance_status, ownership, transitions
from coral_operator.status.conditions import ConditionType, Reason

# A pod refused for good (admission, Pod Security, quota) is tried again this often: the fix may be
# outside the spec (a namespace label, a quota), and nothing else would wake the instance up.
REFUSED_RETRY_S = 30.0


@dataclass(kw_only=True, eq=False)
class InstanceReconciler(Reconciler):
    """One level-based pass per CoralInstance key (namespace, name)."""

    wake_system: Callable[[Key], None] = lambda _key: None
    """Pass the system of this key at once (a verdict its rollout reads was written)."""
    pod_settings: PodSettings = field(default_factory=PodSettings)

    def reconcile(self, key: Key) -> None:
        indexed: InstanceRecord | None = next(
            iter(self.indexes.read("coral_instances", instance_named(*key))), None
        )
        # A system pass that just moved this instance woke this pass with its answer.
        record = self.memory.moved.latest(key, indexed)
        if record is None:
            return
        now = self.clock()
        status = self.memory.statuses.observed(record.uid, record.resource_version, record.status)
        spec = instance_pass.parse_instance_spec(record)
        if isinstance(spec, str):
            self._write_invalid(record, status, spec, now=now)
            return
        node = self._robot(spec.node_name)
        # Whose instance this is comes first: nothing is built for one the operator did not make.
        refusal = self._refusal(record, spec, node)
        if refusal is not None:
            self._refuse(record, status, *refusal, now=now)
            return
        desired: list[dict[str, Any]] = []
        if not spec.retiring:
            parsed = spec
            try:
                desired = self.memory.desired_pods.get(
                    record.uid,
                    record.generation,
                    lambda: instance_pass.build_desired_pods(record, parsed, self.pod_settings),
                )
            except HostPathRefused as refused:
                # The policy check above refuses such a path first; this is the builder's own guard.
                self._write_invalid(record, status, f"Refused by the operator's policy: {refused}", now=now)
                return
        # Each pod's entry holds its records: one for a component pod, one per component for a robot pod.
        every: list[ObservedPod] = [pod for pods in self.indexes.read("coral_pods", key) for pod in pods]
        # A pre-pull pod belongs to the system's rollout; only a failed pull is told here.
        observed = [pod for pod in every if pod.role != PULL_ROLE]
        pulls = [p for p in every if p.role == PULL_ROLE and not p.deleting]
        pre_pull = (pulls[0].revision, pulls[0].image_problem or pulls[0].unschedulable) if pulls else None
        plan = instance_pass.plan_instance(
            record=record, spec=spec, desired=desired, node=node, observed=observed, now=now
        )
        if plan.retire:
            self._retire(record, plan)
            return
        assert plan.startup is not None
        if node is None:
            # A pod pinned to a Node that is no robot's would run wherever that name leads.
            plan.startup.create = []
        refused = self._apply(record, plan, observed)
        if refused:
            self.requeue(key, REFUSED_RETRY_S)
        if plan.startup.wake_at is not None:
            # Pass again when the waiting stage's health timeout falls due, even if nothing changes.
            self.requeue(key, max((plan.startup.wake_at - now).total_seconds(), 0.0) + 0.5)
        report = executor_report.read_executor_report(status)
        view = instance_status.InstanceView(
            spec=spec,
            node=node,
            desired=plan.desired,
            pods=observed,
            plan=plan.startup,
            transient=plan.transient,
            tree=report.tree,
            plugins=report.plugins,
            refused=refused,
            ignored_tree=report.ignored_tree,
            ignored_plugins=report.ignored_plugins,
            pre_pull=pre_pull,
        )
        new = instance_status.build_instance_status(
            view, old_conditions=transitions.written_conditions(status), generation=record.generation, now=now
        )
        self._write_status(record, status, new)

    def _refusal(
        self, record: InstanceRecord, spec: CoralInstanceSpec, node: RobotNode | None
    ) -> tuple[Reason, str] | None:
        """(reason, message) when the instance is not one this operator may build pods for
        (`planning.provenance`); None when it is."""
        system: SystemRecord | None = next(
            iter(self.indexes.read("coral_systems", (record.namespace, spec.system))), None
        )
        problems = provenance.evaluate_ownership(
            name=record.name, owners=record.owners, spec=spec, system=system, node=node
        )
        if problems:
            return Reason.FOREIGN_INSTANCE, _not_served(problems)
        assert system is not None
        if spec.retiring or self.memory.vetted.has(record.uid, record.generation, system.uid):
            return None  # stopping builds nothing; a vetted generation's spec cannot have changed
        problem = provenance.evaluate_revision(
            spec, self._history(system, spec.revision), node, system, self.memory.verdicts
        )
        if problem is not None:
            return Reason.FOREIGN_INSTANCE, _not_served([problem])
        denied = provenance.evaluate_instance_policy(record.namespace, spec, self.pod_settings.policy)
        if denied:
            refusals = "; ".join(denied)
            return Reason.POLICY_DENIED, f"Not served, the operator's policy refuses: {refusals}."
        self.memory.vetted.add(record.uid, record.generation, system.uid)
        return None

    def _history(self, system: SystemRecord, revision: str) -> list[StoredRevision]:
        """The system's revisions, read from the API only when this process does not hold one
        with `revision` (a system pass may store it any moment, and a restarted operator holds none)."""
        key = (system.namespace, system.name, system.uid)
        known = self.memory.histories.known(key)
        if known is not None and any(stored.revision == revision for stored in known):
            return known
        read = self.writer.read_revisions(*key)
        self.memory.histories.offer(key, read)
        return read

    def _refuse(
        self, record: InstanceRecord, status: dict[str, Any], reason: Reason, message: str, *, now: datetime
    ) -> None:
        """Build nothing, delete nothing, and say why: on the status and in one Event per new reason."""
        old = transitions.written_conditions(status)
        before = transitions.find(old, ConditionType.STALLED) or {}
        new = instance_status.build_invalid_status(
            message, old_conditions=old, generation=record.generation, now=now, reason=reason
        )
        self._write_status(record, status, new, post_events=False)
        if (before.get("reason"), before.get("message")) != (reason.value, message):
            self.post(record.reference, "Warning", reason.value, message)

    def _write_invalid(
        self, record: InstanceRecord, status: dict[str, Any], message: str, *, now: datetime
    ) -> None:
        new = instance_status.build_invalid_status(
            message,
            old_conditions=transitions.written_conditions(status),
            generation=record.generation,
            now=now,
        )
        self._write_status(record, status, new)

    def _robot(self, node_name: str) -> RobotNode | None:
        node: RobotNode | None = next(iter(self.indexes.read("robot_nodes", ("node", node_name))), None)
        if node is not None and not node.reachable:
            # The Lease says when the robot was last heard from; it no longer changes while it is away.
            node = dataclasses.replace(
                node, last_seen=self.writer.read_renew_time(node.node_name) or node.last_seen
            )
        return node

    def _apply(
        self, record: InstanceRecord, plan: instance_pass.InstancePlan, observed: list[ObservedPod]
    ) -> dict[str, str]:
        """Carry out the startup plan, but for the creates and deletes of earlier passes the index
        does not show yet; returns the pods the API server refused for good, with its messages,
        keyed by `instance_pass.refusal_key`."""
        assert plan.startup is not None
        namespace = record.namespace
        refused: dict[str, str] = {}
        created, deleted = self.memory.creates.in_flight(
            record.uid, {pod.name: pod.deleting for pod in observed}
        )
        delete = [name for name in plan.startup.delete if name not in deleted]
        if delete and plan.startup.delete_selector is not None:
            self.writer.delete_pods(namespace, plan.startup.delete_selector)
        else:
            for pod_name in delete:
                self.writer.delete_pod(namespace, pod_name)
        made = []
        for manifest in plan.startup.create:
            if instance_pass.refusal_key(manifest) in refused or manifest["metadata"]["name"] in created:
                continue
            try:
                self.writer.create_pod(manifest)
                made.append(manifest["metadata"]["name"])
            except Exception as error:
                message = applying.refusal(error)
                if message is None:
                    raise
                refused[instance_pass.refusal_key(manifest)] = message
        self.memory.creates.expect(record.uid, made, delete)
        for pod_name, labels in plan.startup.relabel:
            self.writer.patch_pod_labels(namespace, pod_name, labels)
        for pod_name, patch in plan.startup.set_images:
            self.writer.patch_pod(namespace, pod_name, patch)
        return refused

    def _retire(self, record: InstanceRecord, plan: instance_pass.InstancePlan) -> None:
        """Stop the robot's components in reverse startup order, then remove the instance."""
        if plan.delete_instance:
            self.writer.delete_instance(record.namespace, record.name)
            return
        for pod_name in plan.stop:
            self.writer.delete_pod(record.namespace, pod_name)

    def _write_status(
        self,
        record: InstanceRecord,
        current: dict[str, Any],
        new: dict[str, Any],
        *,
        post_events: bool = True,
    ) -> None:
        changed = {key: value for key, value in new.items() if current.get(key) != value}
        if not changed:
            return
        since: float | None = None
        anchor = status_pacing.can_wait(current, new, record.generation)
        if anchor is status_pacing.Anchor.LAST_WRITE:
            _, _, since = self.memory.statuses.last(record.uid)
        elif anchor is status_pacing.Anchor.GENERATION_SEEN:
            since = self.memory.pacing.generation_seen_at(record.uid, record.generation)
        if since is not None:
            robots = self.indexes.count(
                "coral_instances", instances_of_system(record.namespace, record.spec.get("system", ""))
            )
            wait = status_pacing.wait_left(
                since=since,
                now=self.memory.clock(),
                deferred_writes=self.memory.pacing.deferred_writes(record.uid),
                robots=robots,
            )
            if wait > 0:
                # It rides along with the next verdict, or goes out when this is due.
                self.requeue((record.namespace, record.name), wait)
                return
        changes = {key: _patch_value(current.get(key), value) for key, value in changed.items()}
        version = self.writer.patch_instance_status(record.namespace, record.name, changes)
        if version is None:
            return
        after = {key: value for key, value in {**current, **changed}.items() if value is not None}
        self.memory.statuses.remember(
            record.uid, version, ownership.operator_part(after), replaced=record.resource_version
        )
        self.memory.pacing.wrote(record.uid, deferred=since is not None)
        system = record.spec.get("system")
        if system and _system_reads_a_change(record, current, after):
            # At once, not when the watch brings this write back: the system pass reads it from
            # memory meanwhile, and a rollout's next robots wait on it.
            self.wake_system((record.namespace, system))
        if not post_events:
            return
        # After the write, so a deferred or failed one cannot post the same transition twice. Only
        # warnings: the good news of a fleet is counted on its system, not told per robot.
        for kind, reason, message in events.condition_events(
            transitions.written_conditions(current), list(new.get("conditions") or []), warnings_only=True
        ):
            self.post(record.reference, kind, reason, message)


def _not_served(problems: list[str]) -> str:
    return "Not served, this CoralInstance is not one its CoralSystem made: " + "; ".join(problems) + "."


def _patch_value(old: Any, new: Any) -> Any:
    # A merge patch merges objects key by key: keys the new value lacks must be sent as null, or
    # the old ones (or forged ones) would stay.
    if isinstance(old, dict) and isinstance(new, dict):
        return {**{key: None for key in old if key not in new}, **new}
    return new


def _system_reads_a_change(record: InstanceRecord, before: dict[str, Any], after: dict[str, Any]) -> bool:
    """Whether a status write changes what the instance's system reads of it."""
    instance = observing.observed_instance(
        {"metadata": {"generation": record.generation}, "spec": record.spec}
    )

    def seen(status: dict[str, Any]) -> tuple[Any, ...]:
        return observing.summary_of(observing.with_operator_status(instance, status))

    return seen(before) != seen(after)
