"""Computes the operator-owned part of a CoralInstance's status (the executor owns `tree`, `plugins`).

`Ready` comes from an ordered chain of small checks; the first that fails gives reason and
message. Pure; called by `reconcile.instances` with the observed state and the clock.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from coral_core.instance_status import PluginState, TreeHalt, TreeState

from coral_operator.api import keys
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.planning.observed import ObservedPod, RobotNode
from coral_operator.planning.startup import StartupPlan, component_slots, counts_as_ready, current_record
from coral_operator.status import executor_report
from coral_operator.status.conditions import ConditionType as C
from coral_operator.status.conditions import Reason as R
from coral_operator.status.transitions import Verdict, merge_conditions, parse_rfc3339, rfc3339


@dataclass(frozen=True)
class InstanceView:
    """Everything the instance's status is computed from."""

    spec: CoralInstanceSpec
    node: RobotNode | None
    desired: list[dict[str, Any]]
    pods: list[ObservedPod]
    plan: StartupPlan
    transient: set[str]
    tree: TreeState | None
    plugins: PluginState | None
    refused: Mapping[str, str] = field(default_factory=dict)
    """Components whose pod the API server refused in this pass, with the server's message."""
    ignored_tree: list[str] = field(default_factory=list)
    """Fields of the executor's `tree` left out as unreadable, one sentence each
    (`status.executor_report`); `tree` holds the rest."""
    ignored_plugins: list[str] = field(default_factory=list)
    """The same for `plugins`."""
    pre_pull: tuple[str, str | None] | None = None
    """(revision, why its images cannot be pulled, or None) while the robot pre-pulls a revision."""


def _robot_verdict(view: InstanceView) -> Verdict:
    if view.node is None:
        return Verdict(
            C.ROBOT_REACHABLE, False, R.NODE_MISSING, f"Node {view.spec.node_name} does not exist."
        )
    if not view.node.reachable:
        seen = rfc3339(view.node.last_seen) if view.node.last_seen else "never"
        return Verdict(
            C.ROBOT_REACHABLE,
            False,
            R.NODE_UNREACHABLE,
            f"Robot {view.spec.robot} is unreachable (Node {view.node.node_name} stopped reporting, "
            f"last seen {seen}); its pods are kept.",
        )
    return Verdict(C.ROBOT_REACHABLE, True, R.NODE_READY, f"Node {view.node.node_name} reports in.")


def _node_ready(view: InstanceView) -> Verdict:
    """The Node link of the Ready chain: a reachable robot whose kubelet says it is not Ready."""
    if view.node is not None and not view.node.ready:
        detail = f": {view.node.ready_message}" if view.node.ready_message else ""
        return Verdict(
            C.READY,
            False,
            R.NODE_NOT_READY,
            f"Robot {view.spec.robot} is reachable but its Node {view.node.node_name} is not Ready{detail}",
        )
    return Verdict(C.READY, True, R.NODE_READY)


_POD_PROBLEMS: tuple[tuple[Callable[[ObservedPod], str | None], R, str], ...] = (
    (lambda p: p.image_problem, R.IMAGE_PULL_FAILED, "Image cannot be pulled for"),
    (
        lambda p: p.container_refused,
        R.CONTAINER_REFUSED,
        "The robot's kubelet refuses to create the container of",
    ),
    (lambda p: p.unschedulable, R.POD_UNSCHEDULABLE, "The robot cannot run the pod of"),
)
"""What keeps a pod that is not being deleted from starting, with its reason and the words that
introduce it; the first one any pod has is the one told."""


def _delivery_verdict(view: InstanceView) -> Verdict | None:
    """Why a component pod cannot even start, in the words of whoever refused it; None if none."""
    if view.refused:
        details = "; ".join(f"{name}: {message}" for name, message in sorted(view.refused.items()))
        return Verdict(
            C.COMPONENTS_READY, False, R.POD_REFUSED, f"The API server refused the pod of {details}"
        )
    for problem, reason, told in _POD_PROBLEMS:
        found = sorted(f"{p.component}: {problem(p)}" for p in view.pods if problem(p) and not p.deleting)
        if found:
            return Verdict(C.COMPONENTS_READY, False, reason, f"{told} {'; '.join(found)}")
    return None


def _components_verdict(view: InstanceView) -> Verdict:
    delivery = _delivery_verdict(view)
    if delivery is not None:
        return delivery
    crashing = [
        p.component
        for p in view.pods
        if p.crash_looping or (p.phase == "Failed" and p.component not in view.transient)
    ]
    if crashing:
        return Verdict(
            C.COMPONENTS_READY,
            False,
            R.COMPONENT_FAILED,
            f"Components failing: {', '.join(sorted(crashing))}.",
        )
    if view.plan.timed_out:
        return Verdict(C.COMPONENTS_READY, False, R.HEALTH_TIMEOUT, view.plan.message)
    if view.plan.waiting_for == "driver":
        return Verdict(C.COMPONENTS_READY, False, R.WAITING_FOR_DRIVERS, view.plan.message)
    if view.plan.waiting_for == "skillset":
        return Verdict(C.COMPONENTS_READY, False, R.WAITING_FOR_SKILLSETS, view.plan.message)
    if view.plan.delete or view.plan.create or view.plan.set_images:
        names = sorted(
            {
                *view.plan.delete,
                *(m["metadata"]["name"] for m in view.plan.create),
                *(name for name, _ in view.plan.set_images),
            }
        )
        return Verdict(
            C.COMPONENTS_READY, False, R.PODS_UPDATING, f"Pods being created or replaced: {', '.join(names)}."
        )
    slots = component_slots(view.desired)
    unready = [
        slot.component
        for slot in slots
        if not counts_as_ready(current_record(slot, view.pods), slot.component in view.transient)
    ]
    if unready:
        return Verdict(
            C.COMPONENTS_READY, False, R.PODS_NOT_READY, f"Components not ready: {', '.join(unready)}."
        )
    return Verdict(
        C.COMPONENTS_READY, True, R.ALL_COMPONENTS_READY, f"All {len(slots)} components are ready."
    )


def _with_note(verdict: Verdict, ignored: list[str]) -> Verdict:
    """`verdict` naming the executor's fields that were ignored, so a forged or broken report is
    seen where it would have counted."""
    note = executor_report.ignored_note(ignored)
    return (
        verdict if not note else Verdict(verdict.type, verdict.status, verdict.reason, verdict.message + note)
    )


def _plugins_verdict(view: InstanceView) -> Verdict:
    return _with_note(_plugins_reported(view), view.ignored_plugins)


def _plugins_reported(view: InstanceView) -> Verdict:
    if view.plugins is None:
        return Verdict(C.PLUGINS_READY, None, R.NO_REPORT, "The executor has not reported plugins yet.")
    missing = view.plugins.missing
    if missing:
        return Verdict(
            C.PLUGINS_READY, False, R.PLUGINS_MISSING, f"No plugin provides: {', '.join(missing)}."
        )
    return Verdict(C.PLUGINS_READY, True, R.PLUGINS_LOADED, "Every node type of the tree has a plugin.")


def _library_verdict(view: InstanceView) -> Verdict:
    degraded = view.plugins.degraded if view.plugins is not None else []
    if degraded:
        return Verdict(
            C.LIBRARY_DEGRADED,
            True,
            R.LIBRARY_LOST,
            f"Skillsets lost under loaded behaviors: {', '.join(degraded)}.",
        )
    return Verdict(C.LIBRARY_DEGRADED, False, R.LIBRARIES_HEALTHY, "Every loaded plugin's skillset is alive.")


def _tree_is_stale(view: InstanceView) -> bool:
    """The report was written before the running executor started (a replaced pod has not reported).

    Without this, a FAILURE from the previous revision would fail the robot on the new one.
    """
    written = parse_rfc3339(view.tree.updated_at) if view.tree is not None else None
    if written is None:
        return False
    live = [p for p in view.pods if not p.deleting and p.created is not None]
    executors = [p for p in live if p.role == "executor"] or live
    # Second precision on both sides: a pod created in the second of the report came after it.
    return any(p.created is not None and p.created >= written for p in executors)


def _tree_verdict(view: InstanceView) -> Verdict:
    return _with_note(_tree_reported(view), view.ignored_tree)


def _tree_reported(view: InstanceView) -> Verdict:
    if view.tree is None:
        return Verdict(C.TREE_HEALTHY, None, R.NO_REPORT, "The executor has not reported tree status yet.")
    if _tree_is_stale(view):
        return Verdict(
            C.TREE_HEALTHY, None, R.NO_REPORT, "The restarted executor has not reported tree status yet."
        )
    root = view.tree.root_status
    if root == "FAILURE":
        failure = view.tree.last_failure
        # An object with no field set says nothing about the failure.
        detail = f" at {failure.path}: {failure.message}" if failure and failure.model_fields_set else ""
        return Verdict(C.TREE_HEALTHY, False, R.TREE_FAILED, f"The tree failed{detail}.")
    stuck = view.tree.no_progress
    if root == "RUNNING" and stuck and stuck.model_fields_set:
        what = f"{stuck.path} has failed the same way since {stuck.since or 'a while'}: {stuck.message}"
        return Verdict(C.TREE_HEALTHY, False, R.NO_PROGRESS, f"The tree makes no progress: {what}")
    return Verdict(C.TREE_HEALTHY, True, R.TREE_OK, f"The tree is {root}.")


def _tree_not_failed(view: InstanceView) -> Verdict:
    """The tree link of the Ready chain: only a FAILURE root breaks it (no report yet does not)."""
    verdict = _tree_verdict(view)
    return verdict if verdict.status is False else Verdict(C.TREE_HEALTHY, True, R.TREE_OK)


def _halt_acknowledged(view: InstanceView) -> TreeHalt | None:
    """The executor's halt acknowledgement, unless it came from an executor that has since restarted."""
    if view.tree is None or _tree_is_stale(view):
        return None
    return view.tree.halted


def _halt_verdict(view: InstanceView) -> Verdict | None:
    """`Halted`: present while a halt is asked for (`spec.halt`) or the executor still says so.

    A halted robot is where its spec asks it to be, so it reads Ready (and kstatus Current), not
    failed; while the executor has not acknowledged a halt or a resume yet, the robot is on its way.
    """
    asked = view.spec.halt is not None
    acknowledged = _halt_acknowledged(view)
    if not asked and acknowledged is None:
        return None
    if asked and acknowledged is None:
        message = "A halt is asked for; the executor has not acknowledged it yet."
        return Verdict(C.HALTED, False, R.HALT_REQUESTED, message)
    assert acknowledged is not None
    since = acknowledged.since or "an unknown time"
    park = acknowledged.park_tree
    ended = acknowledged.park_status or "unknown"
    parked = f"; park tree {park} ended {ended}" if park else ""
    if not asked:
        return Verdict(
            C.HALTED,
            True,
            R.RESUME_REQUESTED,
            f"The halt was lifted; the executor has not resumed the tree yet (halted since {since}).",
        )
    message = f"The tree is halted on request since {since}{parked}."
    return Verdict(C.HALTED, True, R.HALT_ACKNOWLEDGED, message)


def _halt_settled(view: InstanceView) -> Verdict:
    """The halt link of the Ready chain: broken only while a halt or a resume is on its way."""
    verdict = _halt_verdict(view)
    if verdict is None or verdict.reason == R.HALT_ACKNOWLEDGED:
        return Verdict(C.HALTED, True, R.READY)
    return Verdict(C.HALTED, False, verdict.reason, verdict.message)


# Ready = the first failing link of this chain; reachability comes first because nothing else
# observed about an unreachable robot is current.
_READY_CHAIN: list[Callable[[InstanceView], Verdict]] = [
    _robot_verdict,
    _node_ready,
    _components_verdict,
    _tree_not_failed,
    _halt_settled,
]


def evaluate_ready(view: InstanceView) -> Verdict:
    """The `Ready` verdict: the first failing check's reason and message, or Ready."""
    for check in _READY_CHAIN:
        verdict = check(view)
        if verdict.status is not True:
            return Verdict(C.READY, False, verdict.reason, verdict.message)
    halted = " (its tree halted on request)" if view.spec.halt is not None else ""
    return Verdict(
        C.READY, True, R.READY, f"Robot {view.spec.robot} runs revision {view.spec.revision}{halted}."
    )


def build_components(view: InstanceView) -> list[dict[str, Any]]:
    """One entry per component in startup order."""
    entries = []
    groot2_ports = {e.name: e.groot2.port for e in view.spec.executors if e.groot2}
    for slot in component_slots(view.desired):
        # The pod of this content, else the older one still stopping to make way for it.
        pod = current_record(slot, view.pods) or next(
            (p for p in view.pods if p.component == slot.component), None
        )
        entry: dict[str, Any] = {keys.COMPONENT.name: slot.component, keys.COMPONENT.role: slot.role}
        if pod is not None:
            entry |= {
                keys.COMPONENT.pod: pod.name,
                keys.COMPONENT.phase: "Terminating" if pod.deleting else pod.phase,
                keys.COMPONENT.ready: counts_as_ready(pod, slot.component in view.transient),
                keys.COMPONENT.restarts: pod.restarts,
                keys.COMPONENT.revision: pod.revision,
            }
        else:
            entry |= {
                keys.COMPONENT.phase: "Waiting",
                keys.COMPONENT.ready: False,
                keys.COMPONENT.restarts: 0,
            }
        if slot.component in groot2_ports and slot.role == "executor":
            entry[keys.COMPONENT.groot2_port] = groot2_ports[slot.component]
        entries.append(entry)
    return entries


def _stalled_by(view: InstanceView, robot: Verdict, components: Verdict, tree: Verdict) -> Verdict | None:
    """Why the instance cannot get further without a change to the spec or the robot, if it cannot.

    An unreachable robot, a failed component, a pod the API server or a container the kubelet
    refused (a subPath leading out of its folder stays refused until someone removes the link), a
    blocking startup
    timeout and a tree whose root
    returned FAILURE all leave the instance where it is until someone acts; kstatus reads that as
    Failed, not as work still under way.
    """
    if robot.status is not True:
        return robot
    if components.reason in (R.COMPONENT_FAILED, R.POD_REFUSED, R.CONTAINER_REFUSED) or (
        components.reason == R.HEALTH_TIMEOUT and view.spec.startup.on_timeout == "Block"
    ):
        return components
    # A looping tree is not Ready, but not Stalled either: the loop may end by itself (its
    # skillset regains its state, the data arrives).
    if tree.status is False and tree.reason != R.NO_PROGRESS:
        return tree
    return None


def _pre_pull_verdicts(view: InstanceView) -> list[Verdict]:
    """The robot's pull of the rollout's next revision; no condition when it pulls nothing."""
    if view.pre_pull is None:
        return []
    revision, problem = view.pre_pull
    if problem:
        return [
            Verdict(
                C.IMAGES_PRE_PULLED,
                False,
                R.IMAGE_PULL_FAILED,
                f"The images of revision {revision} cannot be pulled, so the robot stays on its "
                f"revision: {problem}",
            )
        ]
    return [
        Verdict(C.IMAGES_PRE_PULLED, True, R.READY, f"Pulling or pulled the images of revision {revision}.")
    ]


def build_instance_status(
    view: InstanceView, *, old_conditions: list[dict[str, Any]], generation: int | None, now: datetime
) -> dict[str, Any]:
    """The operator-owned status fields of the instance (wire format)."""
    robot = _robot_verdict(view)
    components = _components_verdict(view)
    tree = _tree_verdict(view)
    ready = evaluate_ready(view)
    stalled = _stalled_by(view, robot, components, tree)
    reconciling = not ready.status and stalled is None
    verdicts = [
        ready,
        Verdict(
            C.RECONCILING,
            reconciling,
            R.PROGRESSING if reconciling else (stalled.reason if stalled else R.READY),
            # What keeps it from Ready: its components, or a tree that makes no progress.
            ready.message if reconciling else "",
        ),
        Verdict(
            C.STALLED,
            stalled is not None,
            stalled.reason if stalled else R.READY,
            stalled.message if stalled else "",
        ),
        robot,
        components,
        _plugins_verdict(view),
        _library_verdict(view),
        tree,
        *_pre_pull_verdicts(view),
    ]
    halt = _halt_verdict(view)
    if halt is not None:
        verdicts.append(halt)
    revisions = {p.revision for p in view.pods if not p.deleting}
    node = view.node
    return {
        keys.INSTANCE_STATUS.observed_generation: generation,
        keys.INSTANCE_STATUS.conditions: merge_conditions(
            old_conditions, verdicts, generation=generation, now=now
        ),
        keys.INSTANCE_STATUS.revision: revisions.pop()
        if len(revisions) == 1 and not view.plan.create and not view.plan.delete and not view.plan.set_images
        else None,
        keys.INSTANCE_STATUS.robot: {
            keys.ROBOT.node_name: view.spec.node_name,
            keys.ROBOT.reachable: bool(node and node.reachable),
            keys.ROBOT.node_ready: bool(node and node.ready),
            # Written while the robot is away (from its Node Lease, then fixed); a reachable
            # robot was seen just now, and a moving timestamp would cost a write per heartbeat.
            **(
                {keys.ROBOT.last_seen: rfc3339(node.last_seen)}
                if node and node.last_seen and not node.reachable
                else {}
            ),
        },
        keys.INSTANCE_STATUS.components: build_components(view),
    }


def build_invalid_status(
    message: str,
    *,
    old_conditions: list[dict[str, Any]],
    generation: int | None,
    now: datetime,
    reason: R = R.INVALID_SPEC,
) -> dict[str, Any]:
    """The status of an instance the operator builds nothing for: its spec fails validation, it is
    not its system's (`ForeignInstance`) or asks for more than the policy allows (`PolicyDenied`).
    Stalled, with the fields named."""
    conditions = merge_conditions(
        old_conditions,
        [
            Verdict(C.READY, False, reason, message),
            Verdict(C.RECONCILING, False, reason),
            Verdict(C.STALLED, True, reason, message),
        ],
        generation=generation,
        now=now,
    )
    return {keys.INSTANCE_STATUS.conditions: conditions, keys.INSTANCE_STATUS.observed_generation: generation}
