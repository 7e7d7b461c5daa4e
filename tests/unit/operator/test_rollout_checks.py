"""Each check of a rollout pass on its own: one table per rule, inputs -> decision and reason.

The checks are the steps `planning.rollout.plan_rollout` runs in order (`planning.rollout_checks`);
`tests/unit/rollout/test_rollout_decisions.py` tests the whole chain. Rows are named as sentences.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from coral_operator.api.rollout import CanaryStatus, RolledBack, RolloutFailure, RolloutStatus
from coral_operator.api.system import RolloutSpec, UnavailableBudget, parse_max_unavailable
from coral_operator.planning import rollout_checks as checks
from coral_operator.planning.rollout_checks import RobotView

NOW = datetime(2026, 1, 1, 12, 0, tzinfo=UTC)
A, B, C = "rev-a", "rev-b", "rev-c"
HISTORY = (A, B, C)


def robot(name: str = "r1", revision: str | None = C, **fields: Any) -> RobotView:
    return RobotView(robot=name, revision=revision, **{"ready": True, **fields})


def row(sentence: str, *values: Any) -> Any:
    return pytest.param(*values, id=sentence)


@pytest.mark.parametrize(
    ("value", "budget", "of_ten"),
    [
        row("a count is a count", 3, UnavailableBudget(count=3), 3),
        row("a count in a string is a count", "7", UnavailableBudget(count=7), 7),
        row("zero still lets one robot update", 0, UnavailableBudget(count=0), 1),
        row("a percentage rounds up", "25%", UnavailableBudget(percent=25), 3),
        row("a small percentage still lets one robot update", "1%", UnavailableBudget(percent=1), 1),
        row("all robots at once", "100%", UnavailableBudget(percent=100), 10),
    ],
)
def test_max_unavailable_is_parsed_once_into_a_budget(
    value: int | str, budget: UnavailableBudget, of_ten: int
) -> None:
    assert parse_max_unavailable(value) == budget
    assert budget.resolve(10) == of_ten
    assert RolloutSpec(max_unavailable=value).unavailable_budget() == budget


@pytest.mark.parametrize(
    ("value", "total", "expected"),
    [
        row("a tenth of a thousand", "10%", 1000, 100),
        row("a tenth of fifteen rounds up", "10%", 15, 2),
        row("a count larger than the fleet stays", 5, 3, 5),
        row("a count in a string of a hundred", "7", 100, 7),
        row("every robot of forty", "100%", 40, 40),
    ],
)
def test_a_budget_resolves_against_the_matched_robots(value: int | str, total: int, expected: int) -> None:
    assert parse_max_unavailable(value).resolve(total) == expected


@pytest.mark.parametrize(
    ("value", "message"),
    [
        row("a negative count", -1, "at least 0"),
        row("a negative percentage", "-3%", "expected a count or a percentage"),
        row("a word", "ten", "expected a count or a percentage"),
        row("a percentage over 100", "150%", "expected a count or a percentage"),
        row("a space before the sign", "10 %", "expected a count or a percentage"),
        row("a boolean", True, "expected a count or a percentage"),
    ],
)
def test_a_malformed_max_unavailable_names_the_field(value: Any, message: str) -> None:
    with pytest.raises(ValueError, match=rf"^spec\.rollout\.maxUnavailable: .*{message}"):
        parse_max_unavailable(value)


ROLLED_BACK_FROM_C = RolledBack(from_revision=C, to_revision=B, reason="HealthGateFailed")


@pytest.mark.parametrize(
    ("desired", "rolled_back_before", "undo_from", "revision", "reason"),
    [
        row("the newest revision by default", C, None, None, C, "Newest"),
        row("undo returns to the revision before", C, None, C, B, "Undo"),
        row("undo of an older revision than the spec's is ignored", C, None, B, C, "Newest"),
        row("undo of the first revision has nowhere to go", A, None, A, A, "NothingToUndo"),
        row("a rollback lasts while the spec asks for the same revision", C, ROLLED_BACK_FROM_C, None, B,
            "StillRolledBack"),
        row("a newer revision in the spec ends the rollback", "rev-d", ROLLED_BACK_FROM_C, None, "rev-d",
            "Newest"),
    ],
)
def test_target(
    desired: str, rolled_back_before: RolledBack | None, undo_from: str | None, revision: str, reason: str
) -> None:
    previous = RolloutStatus(revision=B, rolled_back=rolled_back_before) if rolled_back_before else None
    target = checks.check_target(desired, (*HISTORY, "rev-d"), previous, undo_from)
    assert (target.revision, target.reason) == (revision, reason)
    assert (target.rolled_back is not None) == (reason in ("Undo", "StillRolledBack"))


@pytest.mark.parametrize(
    ("view", "passed", "failed", "reason"),
    [
        row("a robot on another revision is not judged", robot(revision=B), False, False, "NotOnTarget"),
        row("Ready with a running tree passes", robot(root_status="RUNNING"), True, False, "Healthy"),
        row("Ready before any tree report passes", robot(), True, False, "Healthy"),
        row("Ready with a failed tree fails", robot(root_status="FAILURE"), False, True, "TreeFailed"),
        row("a Stalled instance fails", robot(ready=False, stalled=True), False, True, "Stalled"),
        row("not Ready yet is neither", robot(ready=False), False, False, "NotReady"),
        row("an offline robot's failed tree is stale and not failed",
            robot(online=False, root_status="FAILURE"), False, False, "Offline"),
    ],
)
def test_health_gate(view: RobotView, passed: bool, failed: bool, reason: str) -> None:
    gate = checks.check_gate(view, C)
    assert (gate.passed, gate.failed, gate.reason) == (passed, failed, reason)


FAILED_C = RolloutFailure(revision=C, robots=["r1"], message="m", time="2026-01-01T11:00:00Z")


@pytest.mark.parametrize(
    ("robots", "previous", "resumed", "on_failure", "target", "paused", "event", "reason"),
    [
        row("healthy robots mid-rollout: carry on", [robot(), robot("r2", B)], None, None, "Pause",
            C, False, None, "NoRobotFailing"),
        row("a failing robot mid-rollout pauses", [robot(root_status="FAILURE"), robot("r2", B)], None, None,
            "Pause", C, True, "RolloutFailed", "FailedPause"),
        row("a failing robot mid-rollout rolls back when asked",
            [robot(root_status="FAILURE"), robot("r2", B)], None, None, "Rollback", B, False,
            "RolloutRolledBack", "FailedRollBack"),
        row("a failure after the rollout completed is no rollout failure", [robot(root_status="FAILURE")],
            RolloutStatus(revision=C, complete=True), None, "Rollback", C, False, None, "NotUnderWay"),
        row("a recorded failure keeps the rollout paused", [robot(), robot("r2", B)],
            RolloutStatus(revision=C, failure=FAILED_C), None, "Pause", C, True, None, "FailureRecorded"),
        row("resuming with another time does not clear the failure", [robot(), robot("r2", B)],
            RolloutStatus(revision=C, failure=FAILED_C), "2020-01-01T00:00:00Z", "Pause", C, True, None,
            "FailureRecorded"),
        row("resuming with the failure's time judges afresh", [robot(), robot("r2", B)],
            RolloutStatus(revision=C, failure=FAILED_C), FAILED_C.time, "Pause", C, False, None,
            "NoRobotFailing"),
        row("resumed robots still failing fail again", [robot(stalled=True), robot("r2", B)],
            RolloutStatus(revision=C, failure=FAILED_C), FAILED_C.time, "Pause", C, True, "RolloutFailed",
            "FailedPause"),
    ],
)
def test_failure(
    robots: list[RobotView],
    previous: RolloutStatus | None,
    resumed: str | None,
    on_failure: str,
    target: str,
    paused: bool,
    event: str | None,
    reason: str,
) -> None:
    verdict = checks.check_failure(
        target=checks.check_target(C, HISTORY, previous, None),
        robots=robots,
        history=HISTORY,
        previous=previous,
        resumed=resumed,
        on_failure=on_failure,
        now=NOW,
    )
    assert (verdict.target, verdict.failure is not None, verdict.reason) == (target, paused, reason)
    assert (verdict.event.reason if verdict.event else None) == event
    if reason == "FailedRollBack":
        assert verdict.rolled_back == RolledBack(from_revision=C, to_revision=B, reason="HealthGateFailed")
        assert verdict.previous_revision == A


def test_a_first_revision_has_nowhere_to_go_back_to() -> None:
    verdict = checks.check_failure(
        target=checks.check_target(A, (A,), None, None),
        robots=[robot(revision=A, root_status="FAILURE"), robot("r2", revision=None)],
        history=(A,),
        previous=None,
        resumed=None,
        on_failure="Rollback",
        now=NOW,
    )
    assert (verdict.target, verdict.failure, verdict.reason) == (A, None, "NowhereToGoBack")


def test_an_undo_is_announced_once() -> None:
    target = checks.check_target(C, HISTORY, None, C)
    first = checks.check_failure(
        target=target,
        robots=[robot()],
        history=HISTORY,
        previous=None,
        resumed=None,
        on_failure="Pause",
        now=NOW,
    )
    assert (first.target, first.reason, first.event.reason if first.event else None) == (
        B, "RollingBack", "RolloutRolledBack"
    )
    again = checks.check_failure(
        target=target,
        robots=[robot()],
        history=HISTORY,
        previous=RolloutStatus(revision=B, rolled_back=target.rolled_back),
        resumed=None,
        on_failure="Pause",
        now=NOW,
    )
    assert (again.reason, again.event) == ("RollingBack", None)


CANARY = {"robots": {"matchLabels": {"canary": "yes"}}, "holdSeconds": 60}
SINCE = "2026-01-01T11:59:30Z"


@pytest.mark.parametrize(
    ("policy", "robots", "previous", "rolled_back", "done", "wake_at", "event", "reason"),
    [
        row("no canary set: the fleet moves", {}, [robot()], None, None, True, None, None, "NoCanary"),
        row("no robot is a canary: promoted at once, with nothing to announce", {"canary": CANARY}, [robot()],
            None, None, True, None, None, "NoCanaryRobots"),
        row("a canary not updated yet holds the fleet", {"canary": CANARY}, [robot(revision=B, canary=True)],
            None, None, False, None, None, "NotHealthy"),
        row("a healthy canary starts the hold", {"canary": CANARY}, [robot(canary=True)], None, None, False,
            NOW + timedelta(seconds=60), None, "Holding"),
        row("the hold counts from when the canaries became healthy", {"canary": CANARY}, [robot(canary=True)],
            CanaryStatus(healthy_since=SINCE), None, False, NOW + timedelta(seconds=30), None, "Holding"),
        row("a hold that is over promotes", {"canary": {**CANARY, "holdSeconds": 30}}, [robot(canary=True)],
            CanaryStatus(healthy_since=SINCE), None, True, None, "CanaryPromoted", "Promoted"),
        row("promoted stays promoted without a second Event", {"canary": CANARY},
            [robot(canary=True, ready=False)], CanaryStatus(promoted=True), None, True, None, None,
            "AlreadyPromoted"),
        row("offline canaries are not waited for by default", {"canary": CANARY},
            [robot(canary=True, online=False)], None, None, False, None, None, "NotHealthy"),
        row("a rollback needs no canary", {"canary": CANARY}, [robot(revision=B, canary=True)], None,
            ROLLED_BACK_FROM_C, True, None, None, "RollingBack"),
    ],
)
def test_canary(
    policy: dict[str, Any],
    robots: list[RobotView],
    previous: CanaryStatus | None,
    rolled_back: RolledBack | None,
    done: bool,
    wake_at: datetime | None,
    event: str | None,
    reason: str,
) -> None:
    canary = checks.check_canary(
        policy=RolloutSpec.model_validate(policy),
        robots=robots,
        target=C,
        previous=previous,
        rolled_back=rolled_back,
        now=NOW,
    )
    assert (canary.done, canary.wake_at, canary.reason) == (done, wake_at, reason)
    assert (canary.event.reason if canary.event else None) == event


@pytest.mark.parametrize(
    ("view", "interrupt", "held", "reason"),
    [
        row("a running tree holds its robot", robot(root_status="RUNNING"), False, True, "TreeRunning"),
        row("unless running trees may be interrupted", robot(root_status="RUNNING"), True, False,
            "InterruptAllowed"),
        row("a finished tree does not hold", robot(root_status="SUCCESS"), False, False, "TreeNotRunning"),
        row("a failed tree does not hold", robot(root_status="FAILURE"), False, False, "TreeNotRunning"),
        row("no tree report does not hold", robot(), False, False, "TreeNotRunning"),
        row("an offline robot is left to the offline rule", robot(online=False, root_status="RUNNING"), False,
            False, "Offline"),
    ],
)
def test_update_lock(view: RobotView, interrupt: bool, held: bool, reason: str) -> None:
    lock = checks.check_lock(view, interrupt)
    assert (lock.held, lock.reason) == (held, reason)


ONLINE_OLD = robot("on", B)
OFFLINE_OLD = robot("off", B, online=False, ready=False)
OFFLINE_NEW = robot("off", C, online=False, ready=False)


@pytest.mark.parametrize(
    ("robots", "mode", "waiting", "unavailable", "required", "reason"),
    [
        row("nobody offline", [ONLINE_OLD], "Skip", False, 0, ["on"], "AllOnline"),
        row("Skip leaves offline robots out of completion", [ONLINE_OLD, OFFLINE_OLD], "Skip", False, 0,
            ["on"], "OfflineSkipped"),
        row("Wait holds the fleet for an offline robot not yet updated", [ONLINE_OLD, OFFLINE_OLD], "Wait",
            True, 0, ["on", "off"], "WaitingForOfflineRobots"),
        row("Wait does not hold for an offline robot already updated", [ONLINE_OLD, OFFLINE_NEW], "Wait",
            False, 0, ["on", "off"], "OfflineUpToDate"),
        row("CountUnavailable spends the budget on offline robots", [ONLINE_OLD, OFFLINE_NEW],
            "CountUnavailable", False, 1, ["on", "off"], "OfflineCountedUnavailable"),
    ],
)
def test_offline_robots(
    robots: list[RobotView], mode: str, waiting: bool, unavailable: int, required: list[str], reason: str
) -> None:
    offline = checks.check_offline(robots, C, mode)
    assert (offline.waiting, offline.unavailable, offline.reason) == (waiting, unavailable, reason)
    assert [r.robot for r in offline.required] == required


@pytest.mark.parametrize(
    ("paused", "failure", "waiting", "held", "reason"),
    [
        row("nothing holds the wave", False, None, False, False, "Proceed"),
        row("spec.rollout.paused holds it", True, None, False, True, "Paused"),
        row("a recorded failure holds it", False, FAILED_C, False, True, "FailedHealthGate"),
        row("an offline robot waited for holds it", False, None, True, True, "WaitingForOfflineRobots"),
    ],
)
def test_hold(paused: bool, failure: RolloutFailure | None, waiting: bool, held: bool, reason: str) -> None:
    hold = checks.check_hold(paused=paused, failure=failure, waiting_offline=waiting)
    assert (hold.held, hold.reason) == (held, reason)


@pytest.mark.parametrize(
    ("candidates", "max_unavailable", "unavailable", "moved", "reason"),
    [
        row("nothing left to move", [robot()], 2, 0, [], "NothingToMove"),
        row("the budget caps a wave, by name", [robot("r3", B), robot("r1", B), robot("r2", B)], 2, 0,
            ["r1", "r2"], "BudgetSpent"),
        row("robots already unavailable use the budget", [robot("r1", B), robot("r2", B)], 2, 2, [],
            "BudgetSpent"),
        row("an unavailable robot moves for free", [robot("r1", B, ready=False), robot("r2", B)], 1, 1,
            ["r1"], "BudgetSpent"),
        row("canaries go before others", [robot("r1", B), robot("r2", B, canary=True)], 1, 0, ["r2"],
            "BudgetSpent"),
        row("a budget big enough moves everyone", [robot("r1", B), robot("r2", B)], 5, 0, ["r1", "r2"],
            "AllMoved"),
    ],
)
def test_wave(
    candidates: list[RobotView], max_unavailable: int, unavailable: int, moved: list[str], reason: str
) -> None:
    wave = checks.plan_wave(
        candidates=candidates, target=C, max_unavailable=max_unavailable, unavailable=unavailable
    )
    assert (sorted(wave.moves), wave.reason) == (moved, reason)
    assert set(wave.moves.values()) <= {C}


@pytest.mark.parametrize(
    ("required", "moves", "complete", "reason"),
    [
        row("every robot healthy on the target", [robot(), robot("r2")], {}, True, "Complete"),
        row("a robot still moving", [robot()], {"r2": C}, False, "RobotsMoving"),
        row("a robot on the old revision", [robot(), robot("r2", B)], {}, False, "NotAllHealthy"),
        row("a robot with a failed tree", [robot(root_status="FAILURE")], {}, False, "NotAllHealthy"),
        row("no robot at all", [], {}, True, "Complete"),
    ],
)
def test_completion(required: list[RobotView], moves: dict[str, str], complete: bool, reason: str) -> None:
    completion = checks.check_complete(required=required, target=C, moves=moves)
    assert (completion.complete, completion.reason) == (complete, reason)
