"""Conditions follow metav1 semantics; Ready is the first failing link of an ordered chain."""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta
from typing import Any

import pytest
from coral_operator.api import common
from coral_operator.planning import status_pacing
from coral_operator.planning.observed import ObservedInstance
from coral_operator.status import instance_status, system_status
from coral_operator.status.conditions import ConditionType, Reason
from coral_operator.status.rollout import RolloutConditionType, RolloutReason
from coral_operator.status.transitions import Verdict, find, merge_conditions
from operator_specs import NOW, view_with_pods_running

LATER = NOW + timedelta(minutes=5)


def test_the_transition_time_moves_only_when_the_status_flips() -> None:
    first = merge_conditions(
        [], [Verdict(ConditionType.READY, False, Reason.PROGRESSING, "a")], generation=1, now=NOW
    )
    same = merge_conditions(
        first, [Verdict(ConditionType.READY, False, Reason.UPDATING, "b")], generation=2, now=LATER
    )
    assert same[0]["lastTransitionTime"] == first[0]["lastTransitionTime"]
    assert (same[0]["reason"], same[0]["message"], same[0]["observedGeneration"]) == ("Updating", "b", 2)
    flipped = merge_conditions(
        same, [Verdict(ConditionType.READY, True, Reason.READY)], generation=2, now=LATER
    )
    assert flipped[0]["lastTransitionTime"] == "2026-01-01T12:05:00Z"
    assert flipped[0]["status"] == "True"


def _conditions(view: instance_status.InstanceView) -> dict[str, dict[str, Any]]:
    status = instance_status.build_instance_status(view, old_conditions=[], generation=3, now=NOW)
    return {c["type"]: c for c in status["conditions"]}


def test_an_instance_with_every_pod_ready_is_ready(spec_dict: Callable[..., dict[str, Any]]) -> None:
    view = view_with_pods_running(spec_dict())
    status = instance_status.build_instance_status(view, old_conditions=[], generation=3, now=NOW)
    conditions = {c["type"]: c for c in status["conditions"]}
    assert conditions["Ready"]["status"] == "True"
    assert conditions["Reconciling"]["status"] == "False" and conditions["Stalled"]["status"] == "False"
    assert all(c["observedGeneration"] == 3 for c in status["conditions"])
    assert [c["name"] for c in status["components"]] == ["lidar", "slam", "executor"]
    assert status["revision"] == view.spec.revision


def test_an_unreachable_robot_says_when_it_was_last_seen(spec_dict: Callable[..., dict[str, Any]]) -> None:
    conditions = _conditions(view_with_pods_running(spec_dict(), node_ready=False))
    assert conditions["RobotReachable"]["status"] == "False"
    assert "last seen 2026-01-01T12:00:00Z" in conditions["RobotReachable"]["message"]
    assert conditions["Ready"]["reason"] == "NodeUnreachable"


def test_pods_not_ready_make_the_instance_reconciling(spec_dict: Callable[..., dict[str, Any]]) -> None:
    conditions = _conditions(view_with_pods_running(spec_dict(), ready=False))
    assert conditions["Ready"]["status"] == "False"
    assert conditions["Reconciling"]["status"] == "True"
    assert conditions["ComponentsReady"]["reason"] == "WaitingForDrivers"


def test_executor_reports_drive_the_tree_and_plugin_conditions(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    conditions = _conditions(view_with_pods_running(spec_dict()))
    assert (
        conditions["TreeHealthy"]["status"] == "Unknown" and conditions["PluginsReady"]["status"] == "Unknown"
    )
    failed = _conditions(
        view_with_pods_running(
            spec_dict(),
            tree={
                "rootStatus": "FAILURE",
                "lastFailure": {"path": "Main/Sequence/Nav", "message": "timeout"},
            },
            plugins={"missing": ["Nav"], "degraded": ["slam (exited)"]},
        )
    )
    assert (
        failed["TreeHealthy"]["status"] == "False" and "Main/Sequence/Nav" in failed["TreeHealthy"]["message"]
    )
    assert failed["PluginsReady"]["status"] == "False" and "Nav" in failed["PluginsReady"]["message"]
    assert failed["LibraryDegraded"]["status"] == "True"
    # A tree that returned FAILURE stops the robot until someone acts: kstatus must read Failed.
    assert (failed["Ready"]["status"], failed["Ready"]["reason"]) == ("False", "TreeFailed")
    assert (failed["Stalled"]["status"], failed["Stalled"]["reason"]) == ("True", "TreeFailed")
    assert (failed["Reconciling"]["status"], failed["Reconciling"]["reason"]) == ("False", "TreeFailed")


def _instance(
    robot_name: str,
    *,
    ready: bool = True,
    revision: str = "r2",
    reachable: bool = True,
    tree: str | None = None,
    stalled: bool = False,
) -> ObservedInstance:
    return ObservedInstance(
        name=f"s-{robot_name}",
        robot=robot_name,
        spec={},
        revision=revision,
        ready=ready,
        reachable=reachable,
        root_status=tree,
        stalled=stalled,
    )


SYSTEM_CASES = [
    (
        "stalled by a bad tree",
        dict(
            matched=1,
            instances=[_instance("a")],
            problem=system_status.Problem(Reason.INVALID_TREE, "t.xml:3: bad"),
        ),
        ("False", "InvalidTree", "False", "True"),
    ),
    ("no robot matches", dict(matched=0, instances=[]), ("False", "NoMatchingRobots", "False", "False")),
    (
        "an instance is still missing",
        dict(matched=2, instances=[_instance("a")]),
        ("False", "Updating", "True", "False"),
    ),
    (
        "an instance runs an old revision",
        dict(matched=1, instances=[_instance("a", revision="r1")]),
        ("False", "Updating", "True", "False"),
    ),
    (
        "an instance is not ready",
        dict(matched=2, instances=[_instance("a"), _instance("b", ready=False)]),
        ("False", "InstancesNotReady", "True", "False"),
    ),
    (
        "an unreachable robot does not hold Ready back",
        dict(matched=2, instances=[_instance("a"), _instance("b", ready=False, reachable=False)]),
        ("True", "Ready", "False", "False"),
    ),
    (
        "everything ready",
        dict(matched=2, instances=[_instance("a"), _instance("b")]),
        ("True", "Ready", "False", "False"),
    ),
    (
        "a robot whose component failed stalls the system instead of keeping it Reconciling",
        dict(matched=2, instances=[_instance("a"), _instance("b", ready=False, stalled=True)]),
        ("False", "InstancesFailed", "False", "True"),
    ),
    (
        "a robot whose tree returned FAILURE stalls the system",
        dict(
            matched=2, instances=[_instance("a"), _instance("b", tree="FAILURE", ready=False, stalled=True)]
        ),
        ("False", "InstancesFailed", "False", "True"),
    ),
    (
        "an unreachable robot that is Stalled for it does not stall the system",
        dict(
            matched=2, instances=[_instance("a"), _instance("b", ready=False, reachable=False, stalled=True)]
        ),
        ("True", "Ready", "False", "False"),
    ),
    (
        "a rolled-back fleet is Stalled although every robot is Ready on the revision it returned to",
        dict(matched=1, instances=[_instance("a")], rolled_back="Rolled back from revision r3 to r2."),
        ("False", "RolledBack", "False", "True"),
    ),
]


def test_reconciling_false_names_the_stall_never_ready() -> None:
    view = system_status.SystemView(
        matched=1, revision="r2", instances=[_instance("a", stalled=True, ready=False)]
    )
    status = system_status.build_system_status(view, old_conditions=[], generation=4, now=NOW)
    reconciling = find(status["conditions"], ConditionType.RECONCILING)
    assert (reconciling["status"], reconciling["reason"]) == ("False", "InstancesFailed")


def test_a_paused_rollout_is_reconciling_with_reason_rollout_paused() -> None:
    paused = Verdict(
        RolloutConditionType.ROLLOUT_COMPLETE, False, RolloutReason.PAUSED, "The rollout is paused."
    )
    view = system_status.SystemView(
        matched=2, revision="r2", instances=[_instance("a"), _instance("b", revision="r1")], rollout=paused
    )
    status = system_status.build_system_status(view, old_conditions=[], generation=4, now=NOW)
    reconciling = find(status["conditions"], ConditionType.RECONCILING)
    assert (reconciling["status"], reconciling["reason"]) == ("True", "RolloutPaused")


def test_the_system_ready_chain() -> None:
    for story, fields, (ready, reason, reconciling, stalled) in SYSTEM_CASES:
        view = system_status.SystemView(revision="r2", **fields)
        status = system_status.build_system_status(view, old_conditions=[], generation=4, now=NOW)
        got = (
            find(status["conditions"], ConditionType.READY)["status"],
            find(status["conditions"], ConditionType.READY)["reason"],
            find(status["conditions"], ConditionType.RECONCILING)["status"],
            find(status["conditions"], ConditionType.STALLED)["status"],
        )
        assert got == (ready, reason, reconciling, stalled), story


def test_the_system_counts_robots_and_trees_without_listing_them() -> None:
    view = system_status.SystemView(
        matched=3,
        revision="r2",
        instances=[
            _instance("a", tree="RUNNING"),
            _instance("b", tree="FAILURE", reachable=False),
            _instance("c", revision="r1"),
        ],
    )
    status = system_status.build_system_status(view, old_conditions=[], generation=1, now=NOW)
    assert status["robots"] == {"matched": 3, "ready": 3, "updated": 2, "unreachable": 1}
    assert status["trees"] == {"running": 1, "success": 0, "failure": 1, "idle": 1}
    assert find(status["conditions"], ConditionType.ROBOTS_REACHABLE)["message"] == "Unreachable robots: b."


def test_a_tree_failure_written_before_the_executor_restarted_is_not_current(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    """A FAILURE of the previous revision must not fail the robot on the next one (issue 14)."""
    tree = {"rootStatus": "FAILURE", "updatedAt": "2026-01-01T12:30:00Z"}
    fresh = _conditions(view_with_pods_running(spec_dict(), tree=tree))
    assert (fresh["TreeHealthy"]["status"], fresh["Stalled"]["reason"]) == ("False", "TreeFailed")
    restarted = _conditions(
        view_with_pods_running(spec_dict(), tree=tree | {"updatedAt": "2026-01-01T11:00:00Z"})
    )
    assert restarted["TreeHealthy"]["status"] == "Unknown" and restarted["Stalled"]["status"] == "False"


def _written(
    generation: int | None, ready: str, stalled: str = "False", reachable: bool = True
) -> dict[str, Any]:
    return {
        "observedGeneration": generation,
        "conditions": [
            {"type": "Ready", "status": ready, "observedGeneration": generation},
            {"type": "Stalled", "status": stalled, "observedGeneration": generation},
        ],
        "robot": {"reachable": reachable, "nodeReady": reachable},
    }


@pytest.mark.parametrize(
    ("current", "new", "generation", "waits"),
    [
        # An update starting: the old generation's Ready reads as in progress already.
        (_written(1, "True"), _written(2, "False"), 2, True),
        # The same, written for the current generation already: a verdict like any other.
        (_written(2, "True"), _written(2, "False"), 2, False),
        # A new instance: kstatus reads an object without status as Current, so it is written.
        ({}, _written(1, "False"), 1, False),
        # The new generation is Ready, or Stalled: the news readers wait for.
        (_written(1, "True"), _written(2, "True"), 2, False),
        (_written(1, "True"), _written(2, "False", stalled="True"), 2, False),
        # The robot went away meanwhile: the rollout reads reachability whatever the generation.
        (_written(1, "True"), _written(2, "False", reachable=False), 2, False),
    ],
)
def test_a_status_of_an_older_generation_stands_for_progressing_until_a_verdict_arrives(
    current: dict[str, Any], new: dict[str, Any], generation: int, waits: bool
) -> None:
    assert status_pacing.stale_status_says_as_much(current, new, generation) is waits


@pytest.mark.parametrize(
    ("current", "new", "waits"),
    [
        # The CRD's default for a new instance, and a robot that is starting: nothing new to read.
        (common.pending_status(), _written(1, "False"), True),
        # Ready, Stalled or away: the news readers wait for.
        (common.pending_status(), _written(1, "True"), False),
        (common.pending_status(), _written(1, "False", stalled="True"), False),
        (common.pending_status(), _written(1, "False", reachable=False), False),
        # No status at all (a CRD without the default): kstatus reads it as Current.
        ({}, _written(1, "False"), False),
        # The executor wrote its tree first: still the default's conditions, still in progress.
        ({**common.pending_status(), "tree": {"rootStatus": "IDLE"}}, _written(1, "False"), True),
        # A status the operator wrote is judged by its generation, not as pending.
        (_written(1, "False"), _written(1, "False"), False),
    ],
)
def test_the_pending_status_of_a_new_instance_stands_for_starting_until_a_verdict_arrives(
    current: dict[str, Any], new: dict[str, Any], waits: bool
) -> None:
    assert status_pacing.pending_status_says_as_much(current, new) is waits
