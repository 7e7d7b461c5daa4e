"""Turns API bodies (nodes, pods, CoralInstances, CoralSystems) into the plain records planning reads.

Called by the kopf indexers in `handlers.indexing` and by `reconcile.controller`; no API calls,
but it knows API shapes, so it lives beside the client.
"""

from __future__ import annotations

import dataclasses
import re
import threading
import weakref
from collections.abc import Mapping
from datetime import datetime
from typing import Any

from coral_core import names
from coral_core.instance_status import ROOT_STATUSES

from coral_operator.api import keys
from coral_operator.planning import budgets, naming, provenance
from coral_operator.planning.observed import (
    ROBOT_SPEC_FIELDS,
    InstanceRecord,
    ObservedInstance,
    ObservedPod,
    RobotNode,
    SystemRecord,
    shared_spec_key,
)
from coral_operator.status import transitions

parse_time = transitions.parse_rfc3339


def _condition(conditions: Any, ctype: str) -> Mapping[str, Any] | None:
    # Conditions of a CoralInstance may have been written by its executor: anything not shaped
    # like a condition is not one.
    if not isinstance(conditions, list):
        return None
    for condition in conditions:
        if isinstance(condition, Mapping) and condition.get("type") == ctype:
            return condition
    return None


def _mapping(value: Any) -> Mapping[str, Any]:
    return value if isinstance(value, Mapping) else {}


def _root_status(status: Mapping[str, Any]) -> str | None:
    """The executor's `tree.rootStatus`, if it is one (it feeds the system's counts and rollout)."""
    root = _mapping(status.get(keys.INSTANCE_STATUS.tree)).get(keys.TREE.root_status)
    return root if isinstance(root, str) and root in ROOT_STATUSES else None


UNREACHABLE_TAINT = "node.kubernetes.io/unreachable"
"""Set by the node-lifecycle controller when a Node's heartbeats (its Lease) stop."""


def robot_annotations(annotations: Mapping[str, str] | None) -> dict[str, str]:
    """The annotations a robot record keeps: all but Kubernetes' own (`*kubernetes.io/`, `*k8s.io/`),
    which no override needs and which would cost memory on every robot of a large fleet."""
    return {
        key: value
        for key, value in (annotations or {}).items()
        if not re.match(r"^([^/]*\.)?(kubernetes\.io|k8s\.io)/", key)
    }


def robot_node(
    name: str,
    labels: Mapping[str, str],
    status: Mapping[str, Any],
    spec: Mapping[str, Any] | None = None,
    annotations: Mapping[str, str] | None = None,
) -> RobotNode | None:
    """A robot record for a Node labelled `coral.dev/robot`, else None.

    Reachable: the kubelet reports in, so Ready is True or False; the node-lifecycle controller
    turns it Unknown and taints the Node `unreachable` once the kubelet's Lease lapses.
    """
    robot = labels.get(names.LABEL_ROBOT)
    if not robot:
        return None
    ready = _condition(status.get("conditions"), "Ready")
    taints = {t.get("key") for t in (spec or {}).get("taints") or []}
    return RobotNode(
        node_name=name,
        robot=robot,
        labels=dict(labels),
        ready=bool(ready and ready.get("status") == "True"),
        last_seen=parse_time((ready or {}).get("lastHeartbeatTime")),
        reachable=bool(ready and ready.get("status") in ("True", "False"))
        and UNREACHABLE_TAINT not in taints,
        ready_message=str((ready or {}).get("message") or ""),
        annotations=robot_annotations(annotations),
        ready_since=parse_time((ready or {}).get(keys.CONDITION.last_transition_time))
        if (ready or {}).get("status") == "True"
        else None,
    )


def observed_pod(body: Mapping[str, Any]) -> ObservedPod:
    """A component pod record."""
    metadata = body.get("metadata", {})
    labels = metadata.get("labels") or {}
    status = body.get("status") or {}
    statuses = status.get("containerStatuses") or []
    ready = _condition(status.get("conditions"), "Ready")
    # The ownership step is an init container: while the kubelet refuses it, the component's own
    # container only waits (PodInitializing) and would tell nothing.
    every = [*(status.get("initContainerStatuses") or []), *statuses]
    waiting = [((s.get("state") or {}).get("waiting") or {}) for s in every]
    waiting_reasons = {w.get("reason") for w in waiting}
    unready_since = _unready_since(ready)
    return ObservedPod(
        name=metadata.get("name", ""),
        component=labels.get(names.LABEL_COMPONENT, ""),
        role=labels.get(names.LABEL_ROLE, ""),
        revision=labels.get(names.LABEL_REVISION, ""),
        pod_hash=(metadata.get("annotations") or {}).get(names.ANNOTATION_POD_HASH, ""),
        phase=status.get("phase") or "Pending",
        ready=bool(ready and ready.get("status") == "True"),
        created=parse_time(metadata.get("creationTimestamp")),
        deleting=bool(metadata.get("deletionTimestamp")),
        unready_since=unready_since,
        settled=any(_settled(s, unready_since) for s in statuses),
        restarts=sum(int(s.get("restartCount") or 0) for s in statuses),
        crash_looping="CrashLoopBackOff" in waiting_reasons,
        image_problem=_image_problem(every, labels.get(names.LABEL_COMPONENT, "")),
        container_refused=_container_refused(every),
        unschedulable=_unschedulable(status),
    )


def observed_pods(body: Mapping[str, Any]) -> tuple[ObservedPod, ...]:
    """The records of a pod: itself for a component pod, one per component for a robot pod."""
    annotations = (body.get("metadata") or {}).get("annotations") or {}
    if names.ANNOTATION_COMPONENTS not in annotations:
        return (observed_pod(body),)
    return tuple(_robot_pod_members(body))


def _container_phase(state: Mapping[str, Any]) -> str:
    if "running" in state:
        return "Running"
    terminated = state.get("terminated")
    if terminated is not None:
        return "Succeeded" if terminated.get("exitCode") == 0 else "Failed"
    # Not started because an earlier container has not: what a component pod not yet created shows.
    if not state or (state.get("waiting") or {}).get("reason") == "PodInitializing":
        return "Waiting"
    return "Pending"


def _robot_pod_members(body: Mapping[str, Any]) -> list[ObservedPod]:
    metadata = body.get("metadata", {})
    labels = metadata.get("labels") or {}
    annotations = metadata.get("annotations") or {}
    status = body.get("status") or {}
    pod_phase = status.get("phase") or "Pending"
    by_name = {
        s.get("name"): s
        for s in [*(status.get("initContainerStatuses") or []), *(status.get("containerStatuses") or [])]
    }
    spec = body.get("spec") or {}
    images = tuple(
        (c.get("name", ""), c.get("image", ""))
        for c in [*(spec.get("initContainers") or []), *(spec.get("containers") or [])]
    )
    created = parse_time(metadata.get("creationTimestamp"))
    unready_since = _unready_since(_condition(status.get("conditions"), "Ready"))
    unschedulable = _unschedulable(status)
    members = {component for component, _ in naming.pod_members({"metadata": metadata})}
    # A container that is no component's (the ownership step) holds every component back.
    helpers = [s for name, s in by_name.items() if name not in members]
    shared_refusal = _container_refused(helpers)
    shared_image_problem = _image_problem(helpers, "")
    records = []
    for component, role in naming.pod_members({"metadata": metadata}):
        container = by_name.get(component) or {}
        state = container.get("state") or {}
        waiting = state.get("waiting") or {}
        phase, ready = _container_phase(state), bool(container.get("ready"))
        if role != "executor" and pod_phase in ("Succeeded", "Failed"):
            # The kubelet stops the sidecars once the executors end; how they exit says nothing. After
            # a finished mission they count as ready, as the other layout's still running pods do.
            phase, ready = pod_phase, pod_phase == "Succeeded"
        records.append(
            ObservedPod(
                name=metadata.get("name", ""),
                component=component,
                role=role,
                revision=labels.get(names.LABEL_REVISION, ""),
                pod_hash=annotations.get(names.ANNOTATION_POD_HASH, ""),
                phase=phase,
                ready=ready,
                created=_waiting_since(container, created),
                deleting=bool(metadata.get("deletionTimestamp")),
                unready_since=unready_since,
                settled=_settled(container, unready_since),
                restarts=int(container.get("restartCount") or 0),
                crash_looping=waiting.get("reason") == "CrashLoopBackOff",
                image_problem=_image_problem([container], component) or shared_image_problem,
                container_refused=_container_refused([container]) or shared_refusal,
                unschedulable=unschedulable,
                shape_hash=annotations.get(names.ANNOTATION_SHAPE_HASH, ""),
                images=images,
            )
        )
    return records


def _waiting_since(container: Mapping[str, Any], pod_created: datetime | None) -> datetime | None:
    """When the component started waiting to become ready: when its container first started, not when
    its pod was made (earlier components started meanwhile). Once restarted (the kubelet restarts a
    sidecar whose startup probe keeps failing), the pod's creation, so the health timeout still
    falls due."""
    started = ((container.get("state") or {}).get("running") or {}).get("startedAt")
    if started and not container.get("restartCount"):
        return parse_time(started)
    return pod_created


def _unready_since(ready: Mapping[str, Any] | None) -> datetime | None:
    """When a pod that is not Ready last stopped being Ready; None for a Ready pod."""
    if ready is None or ready.get("status") == "True":
        return None
    return parse_time(ready.get(keys.CONDITION.last_transition_time))


def _settled(container: Mapping[str, Any], unready_since: datetime | None) -> bool:
    """Whether the container was ready since it last started: its pod turned unready after the start.

    A pod is Ready only when all its containers are, and it turns unready when its first status is
    written (before any container starts) or when it loses readiness; so a pod that turned unready
    after this container started had it ready in between. The node-lifecycle controller also turns
    the pods of a robot it lost unready: their containers did not restart, so they are settled too.
    """
    state = container.get("state") or {}
    life = state.get("running") or state.get("terminated") or {}
    started = parse_time(life.get("startedAt"))
    return started is not None and unready_since is not None and unready_since > started


_IMAGE_PROBLEMS = frozenset(
    {
        "ErrImagePull",
        "ImagePullBackOff",
        "InvalidImageName",
        "ErrImageNeverPull",
    }
)
# The kubelet cannot even create the container from its spec: a subPath leading out of its volume, a
# ConfigMap key missing. It retries, but nothing changes until someone acts.
_CONTAINER_REFUSALS = frozenset({"CreateContainerConfigError"})


def _first_waiting(statuses: list[Mapping[str, Any]], reasons: frozenset[str]) -> tuple[str, str] | None:
    """(container, the kubelet's reason and message) of the first container waiting for one of `reasons`."""
    for container in statuses:
        waiting = (container.get("state") or {}).get("waiting") or {}
        if waiting.get("reason") in reasons:
            return str(container.get("name") or ""), _reason_and_message(waiting)
    return None


def _image_problem(statuses: list[Mapping[str, Any]], own: str) -> str | None:
    """The first image the kubelet cannot pull, in its words, naming the container unless it is the
    component's own `own`: an init step's or a sidecar's failed pull holds the component back as
    surely as its own image would."""
    found = _first_waiting(statuses, _IMAGE_PROBLEMS)
    if found is None:
        return None
    name, told = found
    return told if name == own else f"container {name}: {told}"


def _container_refused(statuses: list[Mapping[str, Any]]) -> str | None:
    found = _first_waiting(statuses, _CONTAINER_REFUSALS)
    return found[1] if found else None


def _reason_and_message(state: Mapping[str, Any]) -> str:
    reason, message = state.get("reason") or "", (state.get("message") or "").strip()
    return f"{reason}: {message[:500]}" if message else reason


def _unschedulable(status: Mapping[str, Any]) -> str | None:
    scheduled = _condition(status.get("conditions"), "PodScheduled")
    if scheduled and scheduled.get("status") == "False" and scheduled.get("reason") == "Unschedulable":
        return _reason_and_message(scheduled)
    # A pod bound to its robot by nodeName skips the scheduler; the kubelet's admission refuses it
    # instead (OutOfcpu, NodeAffinity, ...), failing the pod with a reason and never starting it.
    if status.get("phase") == "Failed" and status.get("reason") and not status.get("containerStatuses"):
        return _reason_and_message(status)
    return None


class InstanceSpec(dict[str, Any]):
    """A CoralInstance spec whose values but the robot's own are those of every other instance
    with the same content (`shared`, kept alive by each spec that uses it)."""

    __slots__ = ("shared", "shared_key")

    shared: dict[str, Any]
    shared_key: str


class _Shared(dict[str, Any]):
    """The part of a spec every robot of one revision has; weakly referenced by `SpecTable`."""

    __slots__ = ("__weakref__",)


class SpecTable:
    """The shared parts of the CoralInstance specs in memory, by content; one per process, held by
    `reconcile.memory.Memory`. A fleet's instances at one revision carry the same components; the
    watch decodes each copy on its own, and keeping each was most of the operator's memory per
    robot (issue 47). Keyed by content (never by the revision a spec claims), so a hand-written
    instance shares nothing it does not hold itself; an entry goes with the last spec using it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._shared: weakref.WeakValueDictionary[str, _Shared] = weakref.WeakValueDictionary()

    def __len__(self) -> int:
        return len(self._shared)

    def share(self, body: Mapping[str, Any]) -> InstanceSpec:
        """The CoralInstance's spec, its shared part deduplicated (see `InstanceSpec`)."""
        spec = body.get("spec") or {}
        key = shared_spec_key(dict(spec))
        with self._lock:
            shared = self._shared.get(key)
            if shared is None:
                shared = _Shared((k, v) for k, v in spec.items() if k not in ROBOT_SPEC_FIELDS)
                self._shared[key] = shared
        # The spec's own key order, so that it reads (and dumps) as the API server sent it.
        result = InstanceSpec((k, spec[k] if k in ROBOT_SPEC_FIELDS else shared[k]) for k in spec)
        result.shared = shared
        result.shared_key = key
        return result


def observed_instance(body: Mapping[str, Any], spec: dict[str, Any] | None = None) -> ObservedInstance:
    """A CoralInstance record as its system sees it; `spec`: `SpecTable.share(body)` to keep it
    shared, else a copy of the body's."""
    metadata = body.get("metadata", {})
    spec = spec if spec is not None else dict(body.get("spec") or {})
    status = _mapping(body.get("status"))
    instance = ObservedInstance(
        name=metadata.get("name", ""),
        robot=spec.get("robot", ""),
        spec=spec,
        revision=spec.get("revision", ""),
        root_status=_root_status(status),
        labels=dict(metadata.get("labels") or {}),
        uid=metadata.get("uid", ""),
        generation=metadata.get("generation"),
        resource_version=metadata.get("resourceVersion"),
        controller_uid=str(
            (provenance.controller_of(metadata.get("ownerReferences") or []) or {}).get("uid", "")
        ),
    )
    if isinstance(spec, InstanceSpec):
        # The hash was made to share the spec; the system pass compares it for every robot.
        instance.__dict__["shared_spec_key"] = spec.shared_key
    return with_operator_status(instance, status)


def with_operator_status(instance: ObservedInstance, status: Mapping[str, Any]) -> ObservedInstance:
    """`instance` with the verdicts of `status` (the operator's part of an instance's status: its
    conditions and robot), read at the instance's generation; the executor's tree stays as it was."""
    conditions = status.get(keys.INSTANCE_STATUS.conditions)
    ready = _condition(conditions, "Ready")
    stalled = _condition(conditions, "Stalled")
    robot = _mapping(status.get(keys.INSTANCE_STATUS.robot))
    reachable, node_ready = robot.get(keys.ROBOT.reachable), robot.get(keys.ROBOT.node_ready)
    return dataclasses.replace(
        instance,
        ready=bool(
            ready
            and ready.get(keys.CONDITION.status) == "True"
            and ready.get(keys.CONDITION.observed_generation) == instance.generation
        ),
        reachable=reachable if isinstance(reachable, bool) else None,
        node_ready=node_ready if isinstance(node_ready, bool) else None,
        # An instance Stalled only because its robot is away is not a failed robot: `reachable`
        # tells that, and the verdict can lag the robot's return by a pass.
        stalled=bool(
            stalled
            and stalled.get(keys.CONDITION.status) == "True"
            and stalled.get(keys.CONDITION.observed_generation) == instance.generation
            and stalled.get(keys.CONDITION.reason) != "NodeUnreachable"
        ),
    )


def instance_record(body: Mapping[str, Any], spec: dict[str, Any] | None = None) -> InstanceRecord:
    """A CoralInstance as its own reconciler reads it; `spec`: `SpecTable.share(body)` to keep it
    shared, else a copy of the body's."""
    metadata = body.get("metadata", {})
    return InstanceRecord(
        name=metadata.get("name", ""),
        namespace=metadata.get("namespace", ""),
        uid=metadata.get("uid", ""),
        generation=metadata.get("generation"),
        spec=spec if spec is not None else dict(body.get("spec") or {}),
        status=dict(_mapping(body.get("status"))),
        resource_version=metadata.get("resourceVersion"),
        owners=tuple(dict(o) for o in metadata.get("ownerReferences") or [] if isinstance(o, Mapping)),
    )


def instance_summary(body: Mapping[str, Any]) -> tuple[Any, ...]:
    """What a system pass reads of one instance: a change here (and only here) calls for one."""
    return summary_of(observed_instance(body))


def summary_of(instance: ObservedInstance) -> tuple[Any, ...]:
    """What a system pass reads of one instance, from its record."""
    return (
        instance.revision,
        instance.ready,
        instance.reachable,
        instance.node_ready,
        instance.root_status,
        instance.stalled,
        bool(instance.spec.get("retiring")),
        tuple(sorted(instance.labels.items())),
        instance.controller_uid,
    )


FILES_KEPT_BYTES = 16 * 1024
"""Inline files (parameters, tree, tree files) up to this size together stay in a system's record."""


def _without_files(spec: dict[str, Any]) -> tuple[dict[str, Any], bool]:
    """`spec` with its inline files emptied when they are large, and whether they were.

    A system's files may be a megabyte, and kept in the index they were most of the operator's
    memory (200 such systems: 470 of its 512 MiB). A pass that needs them reads the system from
    the API (`reconcile.systems`); what the index keeps is everything else, file names included.
    """
    parameters = spec.get("parameters") or {}
    tree = spec.get("tree") or {}
    files = tree.get("files") or {}
    size = len(parameters.get("inline") or "") + len(tree.get("inline") or "")
    size += sum(len(text or "") for text in files.values())
    if size <= FILES_KEPT_BYTES:
        return spec, False
    stripped = dict(spec)
    if parameters.get("inline") is not None:
        stripped["parameters"] = {**parameters, "inline": ""}
    if tree:
        stripped["tree"] = {
            **tree,
            **({"inline": ""} if tree.get("inline") is not None else {}),
            **({"files": dict.fromkeys(files, "")} if files else {}),
        }
    return stripped, True


def system_record(body: Mapping[str, Any], keep_files: bool = False) -> SystemRecord:
    """A CoralSystem as its reconciler reads it; large inline files are left out of the spec
    (`files_left_out`) unless `keep_files`."""
    metadata = body.get("metadata", {})
    full = dict(body.get("spec") or {})
    spec, left_out = (full, False) if keep_files else _without_files(full)
    return SystemRecord(
        name=metadata.get("name", ""),
        namespace=metadata.get("namespace", ""),
        uid=metadata.get("uid", ""),
        generation=metadata.get("generation"),
        spec=spec,
        status=dict(body.get("status") or {}),
        annotations=dict(metadata.get("annotations") or {}),
        resource_version=metadata.get("resourceVersion"),
        created=str(metadata.get("creationTimestamp") or ""),
        spec_bytes=budgets.json_bytes(full),
        share_bytes=budgets.robot_share_bytes(full),
        files_left_out=left_out,
    )
