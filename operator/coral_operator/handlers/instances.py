"""Reconciles a CoralInstance: ordered pod startup, per-robot status.

A fleet has thousands of instances whose pods change in bursts, so the passes do not run inside
kopf's per-event handlers. The handlers here only name the instance that needs a pass (its own
changes, its pods', its robot Node's) on a keyed work queue (`kube.workqueue`); a few worker
threads run one idempotent, level-based pass per instance from kopf's in-memory indexes
(`handlers.indexing`), spaced so a burst of events costs one pass. Pods are planned by
`planning.startup`, status by `status.instance_status` and written with one merge patch when
it changed; the executor's own fields (`tree`, `plugins`) are read, never written, and whatever
else it writes is overwritten by the next pass (`status.ownership`). Pods the API server or an
admission controller refuses are reported on the instance with the server's message. No timers
of kopf's, so no finalizer.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from datetime import UTC, datetime
from typing import Any

import kopf
from pydantic import ValidationError

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.handlers import events
from coral_operator.handlers.indexing import read_index
from coral_operator.kube import applying, leases
from coral_operator.kube.workqueue import WorkQueue
from coral_operator.planning import naming, pods, startup
from coral_operator.planning.observed import InstanceRecord, ObservedPod, RobotNode
from coral_operator.status import instance_status, ownership
from coral_operator.status.conditions import ConditionType, Reason
from coral_operator.status.transitions import Verdict, merge_conditions

CORAL = ("coral.dev", "v1alpha1", "coralinstances")
# Passes of one instance at most this often: a stage's pod is created, scheduled and started in
# quick succession, and one pass (one status write) after the burst is enough.
PASS_INTERVAL_S = 0.1
# Status writes that change no verdict (Ready, Stalled, observed generation) wait this long after
# the previous write, so a robot's startup costs two or three writes instead of one per step.
STATUS_INTERVAL_S = 2.0
WORKERS = 8

Key = tuple[str, str]


_lock = threading.Lock()
# kopf's indexes, handed to every handler; the worker threads read them between events.
_indices: dict[str, Any] = {}
# The status this process last wrote per instance uid: the index may still hold the body from
# before that write, and a pass must neither write the same thing twice nor compute conditions'
# transition times from an older state.
_written: dict[str, tuple[str, dict[str, Any]]] = {}
# Inputs of an instance's own events that call for a pass (spec generation, executor reports);
# the operator's own status writes are not among them.
_inputs: dict[str, tuple[Any, ...]] = {}
# A pod refused for good (admission, Pod Security, quota) is tried again this often: the fix may be
# outside the spec (a namespace label, a quota), and nothing else would wake the instance up.
REFUSED_RETRY_S = 30.0
_node_ready: dict[str, tuple[bool, bool] | None] = {}
# The pods an instance's spec asks for, per uid, with the generation they were built for: a spec
# changes only with its generation, and hashing every pod on every pass is the pass's main cost.
_desired: dict[str, tuple[int | None, list[dict[str, Any]]]] = {}
_last_write: dict[str, float] = {}


def _read(index_name: str, key: Any) -> list[Any]:
    return read_index(_indices.get(index_name), key)


def _reconcile_key(key: Key) -> None:
    records = _read("records", key)
    if not records:
        return
    _reconcile(records[0])


QUEUE: WorkQueue[Key] = WorkQueue(
    _reconcile_key, workers=WORKERS, min_interval_s=PASS_INTERVAL_S, name="coralinstance"
)


@kopf.on.cleanup()
def stop_instance_workers(**_: Any) -> None:
    QUEUE.stop()


def _remember_indices(**indices: Any) -> None:
    """Keep kopf's indexes for the workers, and start the workers on the first event.

    Started from a resource handler, not at startup: only there does the context hold kopf's
    Event poster, which each worker thread inherits.
    """
    _indices.update(indices)
    QUEUE.ensure_started()


@kopf.on.event(*CORAL)
async def instance_changed(
    type: str | None,
    uid: str,
    name: str,
    namespace: str,
    meta: kopf.Meta,
    status: kopf.Status,
    instance_records: kopf.Index,
    coral_pods: kopf.Index,
    robot_nodes: kopf.Index,
    **_: Any,
) -> None:
    """Queue a pass on the instance's own changes: its spec, or what its executor reports."""
    _remember_indices(records=instance_records, pods=coral_pods, nodes=robot_nodes)
    key = (namespace, name)
    if type == "DELETED":
        with _lock:
            _written.pop(uid, None)
            _inputs.pop(uid, None)
            _desired.pop(uid, None)
            _last_write.pop(uid, None)
        QUEUE.forget(key)
        return
    owned = ownership.operator_part(status)
    inputs = (
        meta.get("generation"),
        naming.content_hash(ownership.executor_part(status)),
        naming.content_hash(owned),
    )
    with _lock:
        previous = _inputs.get(uid)
        if previous == inputs:
            return
        _inputs[uid] = inputs
        version, expected = _written.get(uid, (None, None))
    # The echo of the operator's own write changes nothing; any other change to its part of the
    # status (a forged condition) needs a pass to be overwritten.
    echo = version == meta.get("resourceVersion") and owned == expected
    if echo and previous is not None and previous[:2] == inputs[:2]:
        return
    QUEUE.add(key)


@kopf.on.event("pods", labels={naming.LABEL_MANAGED_BY: naming.MANAGER, naming.LABEL_INSTANCE: kopf.PRESENT})
async def pod_changed(
    namespace: str,
    labels: kopf.Labels,
    instance_records: kopf.Index,
    coral_pods: kopf.Index,
    robot_nodes: kopf.Index,
    **_: Any,
) -> None:
    _remember_indices(records=instance_records, pods=coral_pods, nodes=robot_nodes)
    QUEUE.add((namespace, labels[naming.LABEL_INSTANCE]))


@kopf.on.event("nodes", labels={naming.LABEL_ROBOT: kopf.PRESENT})
async def robot_node_changed(
    type: str | None,
    name: str,
    robot_nodes: kopf.Index,
    instances_by_node: kopf.Index,
    instance_records: kopf.Index,
    coral_pods: kopf.Index,
    **_: Any,
) -> None:
    """Queue the robot's instances when it comes or goes; heartbeats alone change nothing here."""
    _remember_indices(records=instance_records, pods=coral_pods, nodes=robot_nodes)
    robot: RobotNode | None = next(iter(robot_nodes.get(("node", name), [])), None)
    # Readiness and reachability move separately (the unreachable taint goes a moment after Ready).
    state = (robot.ready, robot.reachable) if type != "DELETED" and robot is not None else None
    with _lock:
        if _node_ready.get(name) == state:
            return
        _node_ready[name] = state
    for namespace, instance in list(instances_by_node.get(name, [])):
        QUEUE.add((namespace, instance))


def _invalid(error: ValidationError, record: InstanceRecord, status: dict[str, Any]) -> dict[str, Any]:
    message = "; ".join(f"spec.{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in error.errors())
    conditions = merge_conditions(
        list(status.get("conditions") or []),
        [
            Verdict(ConditionType.READY, False, Reason.INVALID_SPEC, message),
            Verdict(ConditionType.RECONCILING, False, Reason.INVALID_SPEC),
            Verdict(ConditionType.STALLED, True, Reason.INVALID_SPEC, message),
        ],
        generation=record.generation,
        now=datetime.now(UTC),
    )
    return {"conditions": conditions, "observedGeneration": record.generation}


def _apply(record: InstanceRecord, spec: CoralInstanceSpec, plan: startup.StartupPlan) -> dict[str, str]:
    """Carry out the plan; returns the pods the API server refused for good, with its messages."""
    namespace = record.namespace
    refused: dict[str, str] = {}
    for pod_name in plan.delete:
        applying.delete_pod(namespace, pod_name)
    if plan.delete:
        # One Event per pass, not per pod: a fleet update replaces thousands of pods.
        events.info(
            record.reference,
            "PodsReplaced",
            f"Stopping {', '.join(plan.delete)} to start revision {spec.revision or '?'}",
        )
    for manifest in plan.create:
        if _pod_component(manifest) in refused:
            continue
        try:
            applying.create_pod(manifest)
        except Exception as error:
            message = applying.refusal(error)
            if message is None:
                raise
            refused[_pod_component(manifest)] = message
    for pod_name, labels in plan.relabel:
        applying.patch_pod_labels(namespace, pod_name, labels)
    for pod_name, patch in plan.set_images:
        applying.patch_pod(namespace, pod_name, patch)
    return refused


def _pod_component(manifest: dict[str, Any]) -> str:
    """What a refusal of this pod is reported under: its component, or the whole robot's pod."""
    return manifest["metadata"]["labels"].get(naming.LABEL_COMPONENT, naming.ROBOT_POD)


def _retire(record: InstanceRecord, observed: list[ObservedPod], reachable: bool) -> None:
    """Stop the robot's components in reverse startup order, then remove the instance."""
    if not observed or not reachable:
        # Nothing left to stop, or no kubelet to stop it: garbage collection takes the rest.
        applying.delete_instance(record.namespace, record.name)
        events.info(
            record.reference,
            "InstanceDeleted",
            f"Deleted CoralInstance {record.name} after stopping its components",
        )
        return
    stopping = startup.plan_shutdown(observed)
    for pod_name in stopping:
        applying.delete_pod(record.namespace, pod_name)
    if stopping:
        events.info(record.reference, "PodsStopped", f"Stopped {', '.join(stopping)} (reverse startup order)")


def _verdicts(status: dict[str, Any]) -> tuple[Any, ...]:
    """What the system's rollout reads of an instance's status: written the moment it changes."""
    states = {c.get("type"): c.get("status") for c in status.get("conditions") or []}
    return status.get("observedGeneration"), states.get("Ready"), states.get("Stalled")


def _patch_value(old: Any, new: Any) -> Any:
    # A merge patch merges objects key by key: keys the new value lacks must be sent as null, or
    # the old ones (or forged ones) would stay.
    if isinstance(old, dict) and isinstance(new, dict):
        return {**{key: None for key in old if key not in new}, **new}
    return new


def _write_status(record: InstanceRecord, current: dict[str, Any], new: dict[str, Any]) -> None:
    changed = {key: value for key, value in new.items() if current.get(key) != value}
    if not changed:
        return
    changes = {key: _patch_value(current.get(key), value) for key, value in changed.items()}
    now = time.monotonic()
    with _lock:
        last = _last_write.get(record.uid, 0.0)
    if _verdicts(current) == _verdicts(new) and now - last < STATUS_INTERVAL_S:
        # Progress only (a stage started, a pod's phase): one write per interval carries it.
        QUEUE.add((record.namespace, record.name), STATUS_INTERVAL_S - (now - last))
        return
    version = applying.patch_instance_status(record.namespace, record.name, changes)
    if version is not None:
        with _lock:
            after = {key: value for key, value in {**current, **changed}.items() if value is not None}
            _written[record.uid] = (version, ownership.operator_part(after))
            _last_write[record.uid] = now
        # After the write, so a deferred or failed one cannot post the same transition twice.
        events.on_condition_changes(
            record.reference, list(current.get("conditions") or []), list(new.get("conditions") or [])
        )


def _desired_pods(record: InstanceRecord, spec: CoralInstanceSpec) -> list[dict[str, Any]]:
    with _lock:
        cached = _desired.get(record.uid)
    if cached is not None and cached[0] == record.generation:
        return cached[1]
    desired = pods.build_pods(
        spec=spec, instance=record.name, namespace=record.namespace, instance_uid=record.uid
    )
    with _lock:
        _desired[record.uid] = (record.generation, desired)
    return desired


def _reconcile(record: InstanceRecord) -> None:
    """One pass over one instance: plan and apply its pods, then write its status if it changed."""
    now = datetime.now(UTC)
    with _lock:
        version, written = _written.get(record.uid, (None, {}))
    # The index may still hold the body from before this process's last write; until it holds
    # that write or a later version, what was written is the operator's part. After that, the
    # object as observed is compared with, so whatever else wrote there is overwritten.
    if ownership.at_or_after(record.resource_version, version):
        status = record.status
    else:
        status = {**record.status, **written}
    try:
        parsed = CoralInstanceSpec.model_validate(record.spec)
    except ValidationError as error:
        _write_status(record, status, _invalid(error, record, status))
        return
    node = next(iter(_read("nodes", ("node", parsed.node_name))), None)
    if node is not None and not node.reachable:
        # The Lease says when the robot was last heard from; it no longer changes while it is away.
        node = dataclasses.replace(node, last_seen=leases.read_renew_time(node.node_name) or node.last_seen)
    # Each pod's entry holds its records: one for a component pod, one per component for a robot pod.
    observed: list[ObservedPod] = [
        pod for records in _read("pods", (record.namespace, record.name)) for pod in records
    ]
    if parsed.retiring:
        _retire(record, observed, node is not None and node.ready)
        return
    desired = _desired_pods(record, parsed)
    transient = {c.name for c in parsed.drivers + parsed.skillsets + parsed.executors if c.transient}
    plan = startup.plan_startup(
        desired=desired, observed=observed, transient=transient, startup=parsed.startup, now=now
    )
    refused = _apply(record, parsed, plan)
    if refused:
        QUEUE.add((record.namespace, record.name), REFUSED_RETRY_S)
    if plan.wake_at is not None:
        # Pass again when the waiting stage's health timeout falls due, even if nothing changes.
        QUEUE.add((record.namespace, record.name), max((plan.wake_at - now).total_seconds(), 0.0) + 0.5)
    view = instance_status.InstanceView(
        spec=parsed,
        node=node,
        desired=desired,
        pods=observed,
        plan=plan,
        transient=transient,
        tree=status.get("tree"),
        plugins=status.get("plugins"),
        refused=refused,
    )
    old_conditions = list(status.get("conditions") or [])
    new = instance_status.build_instance_status(
        view, old_conditions=old_conditions, generation=record.generation, now=now
    )
    _write_status(record, status, new)
