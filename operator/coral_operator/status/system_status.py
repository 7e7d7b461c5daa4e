"""Computes a CoralSystem's status: conditions and robot/tree counts, never a per-robot list.

Pure; called by the system handler. `problem` carries a validation, policy or missing-ConfigMap
failure, which makes the system Stalled while robots keep what they ran.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

from coral_operator.api import keys
from coral_operator.planning.observed import ObservedInstance
from coral_operator.status.conditions import ConditionType as C
from coral_operator.status.conditions import Reason as R
from coral_operator.status.transitions import Verdict, merge_conditions

_TREE_STATES = {
    "RUNNING": keys.TREE_COUNTS.running,
    "SUCCESS": keys.TREE_COUNTS.success,
    "FAILURE": keys.TREE_COUNTS.failure,
}


@dataclass(frozen=True)
class Problem:
    """Why the operator cannot make progress on this spec."""

    reason: R
    message: str


@dataclass(frozen=True)
class SystemView:
    """Everything the system's status is computed from."""

    matched: int
    instances: list[ObservedInstance]
    revision: str | None
    problem: Problem | None = None
    rollout: Verdict | None = None
    """The `RolloutComplete` condition from `status.rollout`, when the system deploys."""
    rolled_back: str | None = None
    """When the fleet is rolled back: a sentence naming the revision left and the one returned to."""


def describe_rollback(rollout: dict[str, Any] | None) -> str | None:
    """A sentence for a rolled-back fleet, from `status.rollout` (wire format); None if not rolled back."""
    back = (rollout or {}).get(keys.ROLLOUT.rolled_back)
    if not back:
        return None
    left = back.get(keys.ROLLED_BACK.from_revision)
    return (
        f"Rolled back from revision {left} to {back.get(keys.ROLLED_BACK.to_revision)} "
        f"({back.get(keys.ROLLED_BACK.reason, 'Undo')}); robots do not run the spec's revision "
        f"{left} until the spec changes."
    )


def count_robots(view: SystemView) -> dict[str, int]:
    """Robot counts over the instances."""
    return {
        keys.ROBOT_COUNTS.matched: view.matched,
        keys.ROBOT_COUNTS.ready: sum(1 for i in view.instances if i.ready),
        keys.ROBOT_COUNTS.updated: sum(
            1 for i in view.instances if view.revision and i.revision == view.revision
        ),
        keys.ROBOT_COUNTS.unreachable: sum(1 for i in view.instances if i.reachable is False),
    }


def count_trees(view: SystemView) -> dict[str, int]:
    """Tree root states over the instances; no report counts as idle."""
    counts = dict.fromkeys(keys.TREE_COUNTS, 0)
    for instance in view.instances:
        counts[_TREE_STATES.get(instance.root_status or "", keys.TREE_COUNTS.idle)] += 1
    return counts


def _online(instance: ObservedInstance) -> bool:
    return instance.reachable is not False and instance.node_ready is not False


def evaluate_ready(view: SystemView, robots: dict[str, int]) -> Verdict:
    """Ready: nothing stalled, robots matched, all on the newest revision, all reachable ones Ready.

    Offline robots (unreachable, or with a Node that is not Ready) do not hold `Ready` back (they
    are told by `RobotsReachable` and their instances), so one robot off the network does not make
    a whole fleet look broken.
    """
    if view.problem is not None:
        return Verdict(C.READY, False, view.problem.reason, view.problem.message)
    if view.rolled_back is not None:
        return Verdict(C.READY, False, R.ROLLED_BACK, view.rolled_back)
    if view.matched == 0:
        return Verdict(C.READY, False, R.NO_MATCHING_ROBOTS, "No robot Node matches spec.robots.")
    # Offline robots (unreachable, or reachable with a Node that is not Ready) update when they
    # come back; they do not hold the rest of the fleet's Ready.
    online = [i for i in view.instances if _online(i)]
    behind = [i for i in online if i.revision != view.revision]
    if len(view.instances) != view.matched or behind:
        return Verdict(
            C.READY,
            False,
            R.UPDATING,
            f"{robots[keys.ROBOT_COUNTS.updated]} of {view.matched} robots run revision {view.revision}.",
        )
    not_ready = sorted(i.robot for i in online if not i.ready)
    if not_ready:
        shown = ", ".join(not_ready[:10]) + (" ..." if len(not_ready) > 10 else "")
        return Verdict(C.READY, False, R.INSTANCES_NOT_READY, f"{len(not_ready)} robots not ready: {shown}.")
    unreachable = robots[keys.ROBOT_COUNTS.unreachable]
    return Verdict(
        C.READY,
        True,
        R.READY,
        f"{robots[keys.ROBOT_COUNTS.ready]} of {view.matched} robots ready at revision {view.revision}"
        + (f" ({unreachable} unreachable)." if unreachable else "."),
    )


def evaluate_stalled(view: SystemView) -> Verdict:
    """Stalled: nothing more happens without a change to the spec or the robots.

    In order: a spec the operator refuses (or a failed health gate), a rollback (robots do not run
    the spec's revision until the spec changes), and reachable robots whose instance is Stalled
    (a component failed, a blocking startup timeout, a tree that returned FAILURE). Unreachable
    robots never make the system Stalled: they are told by `RobotsReachable`.
    """
    if view.problem is not None:
        return Verdict(C.STALLED, True, view.problem.reason, view.problem.message)
    if view.rolled_back is not None:
        return Verdict(C.STALLED, True, R.ROLLED_BACK, view.rolled_back)
    failed = sorted(i.robot for i in view.instances if i.reachable is not False and i.stalled)
    if failed:
        shown = ", ".join(failed[:10]) + (" ..." if len(failed) > 10 else "")
        return Verdict(
            C.STALLED,
            True,
            R.INSTANCES_FAILED,
            f"{len(failed)} robots failed: {shown} (see their CoralInstances).",
        )
    return Verdict(C.STALLED, False, R.READY, "")


def build_system_status(
    view: SystemView, *, old_conditions: list[dict[str, Any]], generation: int | None, now: datetime
) -> dict[str, Any]:
    """The system's status (wire format)."""
    robots = count_robots(view)
    stalled = evaluate_stalled(view)
    ready = evaluate_ready(view, robots)
    if stalled.status:
        ready = Verdict(C.READY, False, stalled.reason, stalled.message)
    reconciling = not stalled.status and not ready.status and ready.reason != R.NO_MATCHING_ROBOTS
    paused = view.rollout is not None and view.rollout.reason == "Paused"
    unreachable = sorted(i.robot for i in view.instances if i.reachable is False)
    reach = (
        Verdict(
            C.ROBOTS_REACHABLE,
            False,
            R.ROBOTS_UNREACHABLE,
            f"Unreachable robots: {', '.join(unreachable[:10])}.",
        )
        if unreachable
        else Verdict(C.ROBOTS_REACHABLE, True, R.ALL_REACHABLE, "Every matched robot is reachable.")
    )
    if reconciling:
        progress = Verdict(
            C.RECONCILING,
            True,
            R.ROLLOUT_PAUSED if paused else ready.reason,
            view.rollout.message if paused and view.rollout is not None else ready.message,
        )
    else:
        # Not working on it: either done (Ready) or stuck, and then the reason says which.
        progress = Verdict(C.RECONCILING, False, stalled.reason if stalled.status else ready.reason, "")
    verdicts = [
        ready,
        progress,
        stalled,
        reach,
        *([view.rollout] if view.rollout is not None else []),
    ]
    status: dict[str, Any] = {
        keys.SYSTEM_STATUS.observed_generation: generation,
        keys.SYSTEM_STATUS.conditions: merge_conditions(
            old_conditions, verdicts, generation=generation, now=now
        ),
        keys.SYSTEM_STATUS.robots: robots,
        keys.SYSTEM_STATUS.trees: count_trees(view),
    }
    if view.revision:
        status[keys.SYSTEM_STATUS.revision] = view.revision
    return status
