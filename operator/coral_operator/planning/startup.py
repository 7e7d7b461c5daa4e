"""Ordered startup of one robot's components: drivers, then skillsets, then executors.

A stage's pods are created only when every pod of the earlier stages is Ready (a transient one:
Succeeded). A stage that stays unready longer than the health timeout either blocks the next stage
(`Block`, said in the plan's verdict) or lets it start (`Proceed`). A pod whose content hash
changed is deleted, and created again by a later pass once it is gone, gated like any other.
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


def _current(pod: ObservedPod | None, desired: dict[str, Any]) -> bool:
    return (
        pod is not None
        and not pod.deleting
        and pod.pod_hash == desired["metadata"]["annotations"][naming.ANNOTATION_POD_HASH]
    )


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
    by_name = {pod.name: pod for pod in observed}
    wanted = {manifest["metadata"]["name"] for manifest in desired}
    for pod in observed:
        if pod.name not in wanted and not pod.deleting:
            plan.delete.append(pod.name)
    gate_open = True
    for stage in STAGES:
        members = [m for m in desired if m["metadata"]["labels"][naming.LABEL_ROLE] == stage]
        for manifest in members:
            name = manifest["metadata"]["name"]
            pod = by_name.get(name)
            if pod is not None and not pod.deleting and not _current(pod, manifest):
                plan.delete.append(name)
            elif _current(pod, manifest):
                labels = manifest["metadata"]["labels"]
                if pod is not None and pod.revision != labels[naming.LABEL_REVISION]:
                    plan.relabel.append((name, {naming.LABEL_REVISION: labels[naming.LABEL_REVISION]}))
            elif pod is None and gate_open:
                plan.create.append(manifest)
        if not gate_open or stage == "executor":
            continue
        unready = [
            m["metadata"]["name"]
            for m in members
            if not (
                _current(by_name.get(m["metadata"]["name"]), m)
                and counts_as_ready(
                    by_name.get(m["metadata"]["name"]),
                    m["metadata"]["labels"][naming.LABEL_COMPONENT] in transient,
                )
            )
        ]
        if not unready:
            continue
        plan.waiting_for = stage
        # Only pods of the current spec count: a replaced pod still terminating was created for the
        # previous revision, and its age says nothing about how long the new one has waited.
        manifests = {m["metadata"]["name"]: m for m in members}
        created = [
            by_name[n].created
            for n in unready
            if n in by_name and by_name[n].created and _current(by_name[n], manifests[n])
        ]
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
