"""Ordered startup of one robot's components: drivers, then skillsets, then executors.

A stage's pods are created only when every pod of the earlier stages is Ready (a transient one:
Succeeded). A stage that stays unready longer than the health timeout either blocks the next stage
(`Block`, said in the plan's verdict) or lets it start (`Proceed`).

Pods are matched to components by their `coral.dev/component` label and content hash, never by
name: a pod's name ends in a digest of its content (`naming.pod_name`), so a changed component's
new pod has a new name. A pod whose component is no longer wanted, or whose content hash changed,
is deleted. A component's pod is created only once no pod of that component is left, not even a
terminating one (a driver holds hardware, so two must never run at once), and then gated like any
other. A current pod of an older revision is relabelled, not restarted.

Pure; called by the instance handler with the clock injected.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from coral_operator.api.system import StartupSpec
from coral_operator.planning import naming
from coral_operator.planning.observed import ObservedPod

STAGES = ("driver", "skillset", "executor")
_STAGE_NAMES = {"driver": "drivers", "skillset": "skillsets", "executor": "executors"}


@dataclass
class StartupPlan:
    """What to do with the pods of one robot, and why the rest waits."""

    create: list[dict[str, Any]] = field(default_factory=list)
    delete: list[str] = field(default_factory=list)
    relabel: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    waiting_for: str | None = None
    """The stage (`driver` or `skillset`) holding back the next one, if any."""
    timed_out: bool = False
    """The waiting stage exceeded the health timeout."""
    wake_at: datetime | None = None
    """When the waiting stage's health timeout falls due, so the plan should be made again then."""
    message: str = ""


def plan_shutdown(observed: list[ObservedPod]) -> list[str]:
    """Pods to delete now to stop a robot in reverse startup order: executors, skillsets, drivers.

    A stage is deleted only once every pod of the later stages is gone.
    """
    for stage in reversed(STAGES):
        members = [pod for pod in observed if pod.role == stage]
        if members:
            return sorted(pod.name for pod in members if not pod.deleting)
    return []


def counts_as_ready(pod: ObservedPod | None, transient: bool) -> bool:
    """Ready, or for a transient component or an executor (a finished mission) finished successfully."""
    if pod is None or pod.deleting:
        return False
    return pod.ready or ((transient or pod.role == "executor") and pod.phase == "Succeeded")


def _component(manifest: dict[str, Any]) -> str:
    return manifest["metadata"]["labels"][naming.LABEL_COMPONENT]


def _pod_hash(manifest: dict[str, Any]) -> str:
    return manifest["metadata"]["annotations"][naming.ANNOTATION_POD_HASH]


def current_pod(manifest: dict[str, Any], observed: list[ObservedPod]) -> ObservedPod | None:
    """The live pod of `manifest`'s component with `manifest`'s content, whatever its name.

    Matched by component label and content hash, not by name, so a pod created under an older
    naming scheme with the same content still counts as current.
    """
    matches = [
        pod
        for pod in observed
        if pod.component == _component(manifest) and pod.pod_hash == _pod_hash(manifest) and not pod.deleting
    ]
    return min(matches, key=lambda pod: pod.name, default=None)


def plan_startup(
    *,
    desired: list[dict[str, Any]],
    observed: list[ObservedPod],
    transient: set[str],
    startup: StartupSpec,
    now: datetime,
) -> StartupPlan:
    """Decide which pods to create, delete and relabel now.

    Args:
        desired: pod manifests from `planning.pods.build_pods`, in startup order.
        observed: the instance's pods as last seen.
        transient: names of transient components.
        startup: the health timeout and what a timeout does.
        now: the clock.
    """
    plan = StartupPlan()
    wanted = {_component(m): _pod_hash(m) for m in desired}
    for pod in observed:
        if not pod.deleting and wanted.get(pod.component) != pod.pod_hash:
            plan.delete.append(pod.name)
    # Terminating pods count too: the replacement must not run beside the pod it replaces.
    present = {pod.component for pod in observed}
    gate_open = True
    for stage in STAGES:
        members = [m for m in desired if m["metadata"]["labels"][naming.LABEL_ROLE] == stage]
        current = {_component(m): current_pod(m, observed) for m in members}
        for manifest in members:
            pod = current[_component(manifest)]
            revision = manifest["metadata"]["labels"][naming.LABEL_REVISION]
            if pod is not None:
                if pod.revision != revision:
                    plan.relabel.append((pod.name, {naming.LABEL_REVISION: revision}))
            elif gate_open and _component(manifest) not in present:
                plan.create.append(manifest)
        if not gate_open or stage == "executor":
            continue
        unready = [
            _component(m)
            for m in members
            if not counts_as_ready(current[_component(m)], _component(m) in transient)
        ]
        if not unready:
            continue
        plan.waiting_for = stage
        # Only pods of the current spec count: a replaced pod still terminating was created for the
        # previous revision, and its age says nothing about how long the new one has waited.
        live = [current[c] for c in unready]
        created = [pod.created for pod in live if pod is not None and pod.created]
        waited = (now - min(created)).total_seconds() if len(created) == len(unready) else 0.0
        what = f"{_STAGE_NAMES[stage].capitalize()} not ready"
        if waited < startup.health_timeout_seconds:
            note = f"Waiting for {_STAGE_NAMES[stage]} to become ready: {', '.join(unready)}."
            if len(created) == len(unready):
                plan.wake_at = min(created) + timedelta(seconds=startup.health_timeout_seconds)
        else:
            plan.timed_out = True
            consequence = (
                "later stages started anyway" if startup.on_timeout == "Proceed" else "later stages blocked"
            )
            note = (
                f"{what} after {startup.health_timeout_seconds} s ({', '.join(unready)}); "
                f"{consequence} (onTimeout={startup.on_timeout})."
            )
        plan.message = f"{plan.message} {note}".strip()
        if not (
            plan.timed_out and startup.on_timeout == "Proceed" and waited >= startup.health_timeout_seconds
        ):
            gate_open = False
    return plan
