"""Ordered startup of one robot's components: drivers, then skillsets, then executors.

A stage's pods are created only when every pod of the earlier stages is Ready (a transient one:
Succeeded). A stage still starting up longer than the health timeout either blocks the next stage
(`Block`, said in the plan's verdict) or lets it start (`Proceed`); the timeout measures startup
only (`startup_began`), never a component that was ready and lost it mid-mission.

Pods are matched to components by their `coral.dev/component` label and content hash, never by
name: a pod's name ends in a digest of its content (`naming.pod_name`), so a changed component's
new pod has a new name. A pod whose component is no longer wanted, or whose content hash changed,
is deleted. A component's pod is created only once no pod of that component is left, not even a
terminating one (a driver holds hardware, so two must never run at once), and then gated like any
other. A current pod of an older revision is relabelled, not restarted.

With `layout: PodPerRobot` the robot has one pod and its kubelet orders the components inside it;
the plan creates, replaces (or, for a change of images only, patches) that pod and reads the
stages from its containers only to report which one is waited for, with the same messages.

Pure; called by the instance handler with the clock injected.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from coral_core import names

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
    delete_selector: dict[str, str] | None = None
    """Labels that select exactly the pods of `delete`, when these are two or more pods of one
    replaced revision: one request then deletes them all (a DeleteAllOf, in Go's terms)."""
    relabel: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    set_images: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    """Robot pods whose change is images only, with the strategic merge patch that brings them up to
    date: the kubelet restarts just the containers whose image changed."""
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
            # A robot pod is listed once per component; deleting it lets its kubelet stop them in
            # reverse order.
            return sorted({pod.name for pod in members if not pod.deleting})
    return []


def counts_as_ready(pod: ObservedPod | None, transient: bool) -> bool:
    """Ready, or for a transient component or an executor (a finished mission) finished successfully."""
    if pod is None or pod.deleting:
        return False
    return pod.ready or ((transient or pod.role == "executor") and pod.phase == "Succeeded")


def _component(manifest: dict[str, Any]) -> str:
    return manifest["metadata"]["labels"][names.LABEL_COMPONENT]


def _pod_hash(manifest: dict[str, Any]) -> str:
    return manifest["metadata"]["annotations"][names.ANNOTATION_POD_HASH]


@dataclass(frozen=True)
class Slot:
    """One component as the status reports it, whichever pod runs it."""

    component: str
    role: str
    pod_hash: str
    """Content hash of the pod that should run it."""


def component_slots(desired: list[dict[str, Any]]) -> list[Slot]:
    """Every component of the desired pods, in startup order."""
    return [
        Slot(component, role, _pod_hash(manifest))
        for manifest in desired
        for component, role in naming.pod_members(manifest)
    ]


def current_record(slot: Slot, observed: list[ObservedPod]) -> ObservedPod | None:
    """The live record of the slot's component in a pod of the slot's content, whatever its name.

    Matched by component and content hash, not by name, so a pod created under an older naming
    scheme with the same content still counts as current.
    """
    matches = [
        pod
        for pod in observed
        if pod.component == slot.component and pod.pod_hash == slot.pod_hash and not pod.deleting
    ]
    return min(matches, key=lambda pod: pod.name, default=None)


def current_pod(manifest: dict[str, Any], observed: list[ObservedPod]) -> ObservedPod | None:
    """The live pod of a component pod manifest, matched by component and content hash."""
    return current_record(Slot(_component(manifest), "", _pod_hash(manifest)), observed)


def startup_began(pod: ObservedPod, robot_since: datetime | None) -> datetime | None:
    """When the component's current startup began, or None when it is not starting up.

    A startup begins when the pod is made, when the pod loses its readiness (its container crashed,
    or its robot lost it) and when the robot turns Ready again after a reboot or an outage
    (`robot_since`); it ends when the component is ready. A component that has been ready since its
    container last started is not starting up, whatever it does next: a long mission or a finished
    transient run is never held to the health timeout.
    """
    if pod.settled:
        return None
    moments = [moment for moment in (pod.created, pod.unready_since, robot_since) if moment is not None]
    return max(moments, default=None)


def _wait(
    plan: StartupPlan,
    stage: str,
    unready: list[str],
    live: list[ObservedPod | None],
    startup: StartupSpec,
    now: datetime,
    robot_since: datetime | None,
) -> bool:
    """Record in the plan that `stage` is not ready; True when the later stages must wait."""
    plan.waiting_for = stage
    # A component whose pod is still to be made has just begun; one that is not starting up does not count.
    began = [startup_began(pod, robot_since) for pod in live if pod is not None]
    starting = [moment for moment in began if moment is not None] if len(began) == len(live) else []
    waited = (now - min(starting)).total_seconds() if starting else 0.0
    what = f"{_STAGE_NAMES[stage].capitalize()} not ready"
    if waited < startup.health_timeout_seconds:
        note = f"Waiting for {_STAGE_NAMES[stage]} to become ready: {', '.join(unready)}."
        if starting:
            plan.wake_at = min(starting) + timedelta(seconds=startup.health_timeout_seconds)
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
    return not (
        plan.timed_out and startup.on_timeout == "Proceed" and waited >= startup.health_timeout_seconds
    )


def plan_startup(
    *,
    desired: list[dict[str, Any]],
    observed: list[ObservedPod],
    transient: set[str],
    startup: StartupSpec,
    now: datetime,
    robot_since: datetime | None = None,
) -> StartupPlan:
    """Decide which pods to create, delete and relabel now.

    Args:
        desired: pod manifests from `planning.pods.build_pods`, in startup order.
        observed: the instance's pods as last seen.
        transient: names of transient components.
        startup: the health timeout and what a timeout does.
        now: the clock.
        robot_since: when the robot's Node last turned Ready (`RobotNode.ready_since`).
    """
    if len(desired) == 1 and naming.is_robot_pod(desired[0]):
        return _plan_robot_pod(desired[0], observed, transient, startup, now, robot_since)
    plan = StartupPlan()
    wanted = {_component(m): _pod_hash(m) for m in desired}
    for pod in observed:
        # A robot pod (after a layout change) is seen once per component but deleted once.
        if not pod.deleting and wanted.get(pod.component) != pod.pod_hash and pod.name not in plan.delete:
            plan.delete.append(pod.name)
    # Terminating pods count too: the replacement must not run beside the pod it replaces.
    present = {pod.component for pod in observed}
    gate_open = True
    for stage in STAGES:
        members = [m for m in desired if m["metadata"]["labels"][names.LABEL_ROLE] == stage]
        current = {_component(m): current_pod(m, observed) for m in members}
        for manifest in members:
            pod = current[_component(manifest)]
            revision = manifest["metadata"]["labels"][names.LABEL_REVISION]
            if pod is not None:
                if pod.revision != revision:
                    plan.relabel.append((pod.name, {names.LABEL_REVISION: revision}))
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
        # Only pods of the current spec count: a replaced pod still terminating was created for the
        # previous revision, and its age says nothing about how long the new one has waited.
        if _wait(plan, stage, unready, [current[c] for c in unready], startup, now, robot_since):
            gate_open = False
    plan.delete_selector = _replaced_revision(plan.delete, observed, desired)
    return plan


def _replaced_revision(
    delete: list[str], observed: list[ObservedPod], desired: list[dict[str, Any]]
) -> dict[str, str] | None:
    """The labels of the pods to delete when they are all the instance's pods of one revision, and
    that revision is not the one its pods move to (so no pod made for the new one carries it)."""
    if len(delete) < 2 or not desired:
        return None
    doomed = set(delete)
    revisions = {pod.revision for pod in observed if pod.name in doomed}
    labels = desired[0]["metadata"]["labels"]
    if len(revisions) != 1:
        return None
    (revision,) = revisions
    if not revision or revision == labels[names.LABEL_REVISION]:
        return None
    if any(pod.revision == revision and pod.name not in doomed and not pod.deleting for pod in observed):
        return None
    return {
        names.LABEL_INSTANCE: labels[names.LABEL_INSTANCE],
        names.LABEL_REVISION: revision,
        names.LABEL_MANAGED_BY: names.MANAGER,
    }


def _plan_robot_pod(
    manifest: dict[str, Any],
    observed: list[ObservedPod],
    transient: set[str],
    startup: StartupSpec,
    now: datetime,
    robot_since: datetime | None,
) -> StartupPlan:
    """`PodPerRobot`: the kubelet orders the components inside the one pod; the plan replaces the pod
    when it changed (patches it when only images changed), and reads the stages only to report them.
    """
    plan = StartupPlan()
    wanted = _pod_hash(manifest)
    revision = manifest["metadata"]["labels"][names.LABEL_REVISION]
    stale = sorted({pod.name for pod in observed if not pod.deleting and pod.pod_hash != wanted})
    live = [pod for pod in observed if pod.pod_hash == wanted and not pod.deleting]
    for name in stale:
        pod = next(p for p in observed if p.name == name)
        patch = image_patch(manifest, pod) if len(stale) == 1 and not live else None
        if patch is None:
            plan.delete.append(name)
        else:
            plan.set_images.append((name, patch))
    for name in sorted({pod.name for pod in live if pod.revision != revision}):
        plan.relabel.append((name, {names.LABEL_REVISION: revision}))
    # Terminating pods count too: the new pod's drivers must not run beside the old ones.
    if not live and not plan.set_images and not observed:
        plan.create.append(manifest)
    if not live:
        return plan
    slots = component_slots([manifest])
    for stage in STAGES[:-1]:
        # Transient components run beside the executors (`planning.pods.build_robot_pod`): the
        # kubelet starts them after every sidecar, so no stage waits for them.
        members = [slot for slot in slots if slot.role == stage and slot.component not in transient]
        records = {slot.component: current_record(slot, live) for slot in members}
        unready = [c for c, pod in records.items() if not counts_as_ready(pod, c in transient)]
        if unready and _wait(plan, stage, unready, [records[c] for c in unready], startup, now, robot_since):
            break
    return plan


def image_patch(manifest: dict[str, Any], pod: ObservedPod) -> dict[str, Any] | None:
    """The patch turning the robot pod `pod` into `manifest` when they differ in images only, else None."""
    annotations = manifest["metadata"]["annotations"]
    if not pod.shape_hash or pod.shape_hash != annotations.get(names.ANNOTATION_SHAPE_HASH):
        return None
    running = dict(pod.images)
    spec: dict[str, Any] = {}
    for group in ("initContainers", "containers"):
        changed = [
            {"name": c["name"], "image": c["image"]}
            for c in manifest["spec"].get(group, [])
            if running.get(c["name"]) != c["image"]
        ]
        if changed:
            spec[group] = changed
    return {
        "metadata": {
            "labels": {names.LABEL_REVISION: manifest["metadata"]["labels"][names.LABEL_REVISION]},
            "annotations": {names.ANNOTATION_POD_HASH: _pod_hash(manifest)},
        },
        "spec": spec,
    }
