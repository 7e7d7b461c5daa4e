"""Turns API bodies (nodes, pods, CoralInstances) into the plain records planning reads.

Called by the kopf indexers in `handlers.indexing`; no API calls, but it knows API shapes, so
it lives beside the client.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coral_operator.planning import naming
from coral_operator.planning.observed import InstanceRecord, ObservedInstance, ObservedPod, RobotNode
from coral_operator.status import transitions

parse_time = transitions.parse_rfc3339


def _condition(conditions: list[Mapping[str, Any]] | None, ctype: str) -> Mapping[str, Any] | None:
    for condition in conditions or []:
        if condition.get("type") == ctype:
            return condition
    return None


UNREACHABLE_TAINT = "node.kubernetes.io/unreachable"
"""Set by the node-lifecycle controller when a Node's heartbeats (its Lease) stop."""


def robot_node(
    name: str, labels: Mapping[str, str], status: Mapping[str, Any], spec: Mapping[str, Any] | None = None
) -> RobotNode | None:
    """A robot record for a Node labelled `coral.dev/robot`, else None.

    Reachable: the kubelet reports in, so Ready is True or False; the node-lifecycle controller
    turns it Unknown and taints the Node `unreachable` once the kubelet's Lease lapses.
    """
    robot = labels.get(naming.LABEL_ROBOT)
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
    )


def observed_pod(body: Mapping[str, Any]) -> ObservedPod:
    """A component pod record."""
    metadata = body.get("metadata", {})
    labels = metadata.get("labels") or {}
    status = body.get("status") or {}
    statuses = status.get("containerStatuses") or []
    ready = _condition(status.get("conditions"), "Ready")
    waiting_reasons = {((s.get("state") or {}).get("waiting") or {}).get("reason") for s in statuses}
    return ObservedPod(
        name=metadata.get("name", ""),
        component=labels.get(naming.LABEL_COMPONENT, ""),
        role=labels.get(naming.LABEL_ROLE, ""),
        revision=labels.get(naming.LABEL_REVISION, ""),
        pod_hash=(metadata.get("annotations") or {}).get(naming.ANNOTATION_POD_HASH, ""),
        phase=status.get("phase") or "Pending",
        ready=bool(ready and ready.get("status") == "True"),
        created=parse_time(metadata.get("creationTimestamp")),
        deleting=bool(metadata.get("deletionTimestamp")),
        restarts=sum(int(s.get("restartCount") or 0) for s in statuses),
        crash_looping="CrashLoopBackOff" in waiting_reasons,
    )


def observed_instance(body: Mapping[str, Any]) -> ObservedInstance:
    """A CoralInstance record as its system sees it."""
    metadata = body.get("metadata", {})
    spec = dict(body.get("spec") or {})
    status = body.get("status") or {}
    ready = _condition(status.get("conditions"), "Ready")
    stalled = _condition(status.get("conditions"), "Stalled")
    robot = status.get("robot") or {}
    return ObservedInstance(
        name=metadata.get("name", ""),
        robot=spec.get("robot", ""),
        spec=spec,
        revision=spec.get("revision", ""),
        ready=bool(
            ready
            and ready.get("status") == "True"
            and ready.get("observedGeneration") == metadata.get("generation")
        ),
        reachable=robot.get("reachable"),
        node_ready=robot.get("nodeReady"),
        tree_root=(status.get("tree") or {}).get("rootStatus"),
        labels=dict(metadata.get("labels") or {}),
        # An instance Stalled only because its robot is away is not a failed robot: `reachable`
        # tells that, and the verdict can lag the robot's return by a pass.
        stalled=bool(
            stalled
            and stalled.get("status") == "True"
            and stalled.get("observedGeneration") == metadata.get("generation")
            and stalled.get("reason") != "NodeUnreachable"
        ),
    )


def instance_record(body: Mapping[str, Any]) -> InstanceRecord:
    """A CoralInstance as its own reconciler reads it."""
    metadata = body.get("metadata", {})
    return InstanceRecord(
        name=metadata.get("name", ""),
        namespace=metadata.get("namespace", ""),
        uid=metadata.get("uid", ""),
        generation=metadata.get("generation"),
        spec=dict(body.get("spec") or {}),
        status=dict(body.get("status") or {}),
    )
