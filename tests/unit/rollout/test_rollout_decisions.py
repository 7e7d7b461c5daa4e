"""The rollout planner: waves within maxUnavailable, canaries first, lock, offline robots, rollback.

Table-driven over `planning.rollout.plan_rollout`, which is pure: every case builds a fleet of
`RobotView`s, asks for one decision and checks what a fleet operator would see (which robots move,
what `status.rollout` says, which Events are posted).
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from coral_operator.api.rollout import RolloutStatus
from coral_operator.api.system import RolloutSpec
from coral_operator.planning.rollout import RobotView, RolloutRequest, plan_rollout

NOW = datetime(2026, 1, 1, 12, 0, tzinfo=UTC)
OLD, NEW = "old0000000", "new0000000"


def fleet(count: int, revision: str = OLD, **overrides: Any) -> list[RobotView]:
    return [RobotView(robot=f"r{i:03d}", revision=revision, ready=True, **overrides) for i in range(count)]


def replace(robots: list[RobotView], index: int, **changes: Any) -> list[RobotView]:
    robot = robots[index]
    robots[index] = RobotView(**{**robot.__dict__, **changes})
    return robots


def decide(
    robots: list[RobotView],
    previous: RolloutStatus | None = None,
    now: datetime = NOW,
    undo_from: str | None = None,
    resumed: str | None = None,
    history: tuple[str, ...] = (OLD, NEW),
    **policy: Any,
) -> Any:
    return plan_rollout(
        RolloutRequest(
            desired=NEW,
            history=history,
            robots=robots,
            policy=RolloutSpec.model_validate(policy),
            previous=previous,
            now=now,
            undo_from=undo_from,
            resumed=resumed,
        )
    )


@pytest.mark.parametrize(
    ("robots", "max_unavailable", "expected_moves"),
    [
        ("ten ready robots", 2, 2),
        ("ten ready robots", "30%", 3),
        ("one unready robot moves for free and uses its share", 2, 2),
        ("two robots already updating use the budget", 2, 0),
    ],
)
def test_a_wave_never_makes_more_robots_unavailable_than_allowed(
    robots: str, max_unavailable: Any, expected_moves: int
) -> None:
    fleet_now = fleet(10)
    if robots == "one unready robot moves for free and uses its share":
        replace(fleet_now, 5, ready=False)
    if robots == "two robots already updating use the budget":
        replace(fleet_now, 0, revision=NEW, ready=False)
        replace(fleet_now, 1, revision=NEW, ready=False)
    decision = decide(fleet_now, maxUnavailable=max_unavailable)
    assert len(decision.moves) == expected_moves
    assert set(decision.moves.values()) <= {NEW}
    assert decision.status.counts.unavailable <= decision.status.counts.max_unavailable


@pytest.mark.parametrize("seed", range(6))
def test_a_whole_rollout_stays_within_max_unavailable_at_every_pass(seed: int) -> None:
    """Simulates passes in which moved robots take a few passes to become Ready again."""
    import random

    rng = random.Random(seed)
    robots = {r.robot: r for r in fleet(40)}
    recovering: dict[str, int] = {}
    previous = None
    for step in range(200):
        decision = decide(list(robots.values()), previous=previous, maxUnavailable="10%")
        previous = decision.status
        for name, revision in decision.moves.items():
            robots[name] = RobotView(robot=name, revision=revision, ready=False)
            recovering[name] = rng.randint(1, 4)
        for name in list(recovering):
            recovering[name] -= 1
            if recovering[name] <= 0:
                robots[name] = RobotView(robot=name, revision=robots[name].revision, ready=True)
                del recovering[name]
        assert sum(1 for r in robots.values() if not r.ready) <= 4, f"step {step}"
        if decision.status.complete:
            break
    assert decision.status.complete
    assert all(r.revision == NEW for r in robots.values())
    assert [e.reason for e in decision.events] == ["RolloutComplete"]


def test_canaries_move_first_and_the_rest_waits_for_the_hold_time() -> None:
    robots = fleet(6)
    replace(robots, 4, canary=True)
    replace(robots, 5, canary=True)
    policy = {"maxUnavailable": 3, "canary": {"robots": {"matchLabels": {"c": "y"}}, "holdSeconds": 60}}
    first = decide(robots, **policy)
    assert first.moves == {"r004": NEW, "r005": NEW}
    # Canaries updated and healthy: the hold starts, nobody else moves, a wake-up is asked for.
    replace(robots, 4, revision=NEW)
    replace(robots, 5, revision=NEW)
    holding = decide(robots, previous=first.status, **policy)
    assert holding.moves == {}
    assert holding.wake_at == NOW + timedelta(seconds=60)
    assert holding.status.canary.healthy_since == "2026-01-01T12:00:00Z"
    still = decide(robots, previous=holding.status, now=NOW + timedelta(seconds=59), **policy)
    assert still.moves == {}
    promoted = decide(robots, previous=still.status, now=NOW + timedelta(seconds=60), **policy)
    assert promoted.status.canary.promoted
    assert set(promoted.moves) == {"r000", "r001", "r002"}
    assert "CanaryPromoted" in [e.reason for e in promoted.events]


def test_a_canary_that_stops_being_ready_restarts_the_hold() -> None:
    robots = fleet(3, canary=False)
    replace(robots, 0, canary=True, revision=NEW)
    policy = {"canary": {"robots": {"matchLabels": {"c": "y"}}, "holdSeconds": 60}}
    holding = decide(robots, **policy)
    replace(robots, 0, ready=False)
    reset = decide(robots, previous=holding.status, now=NOW + timedelta(seconds=30), **policy)
    assert reset.status.canary.healthy_since is None
    replace(robots, 0, ready=True)
    again = decide(robots, previous=reset.status, now=NOW + timedelta(seconds=70), **policy)
    assert again.status.canary.healthy_since == "2026-01-01T12:01:10Z"
    assert again.moves == {}


@pytest.mark.parametrize("how", ["tree failure", "stalled instance"])
def test_an_unhealthy_canary_pauses_the_rollout_and_no_other_robot_moves(how: str) -> None:
    robots = fleet(5)
    change = {"root_status": "FAILURE"} if how == "tree failure" else {"stalled": True, "ready": False}
    replace(robots, 0, canary=True, revision=NEW, **change)
    policy = {"canary": {"robots": {"matchLabels": {"c": "y"}}, "holdSeconds": 10}, "onFailure": "Pause"}
    decision = decide(robots, **policy)
    assert decision.moves == {}
    assert decision.status.paused and decision.status.failure.revision == NEW
    assert decision.status.failure.robots == ["r000"]
    assert [e.reason for e in decision.events] == ["RolloutFailed"]
    assert all(e.warning for e in decision.events)
    # The failure is remembered: the next pass, even with the canary recovered, still moves nobody.
    replace(robots, 0, root_status="SUCCESS", stalled=False, ready=True)
    later = decide(robots, previous=decision.status, now=NOW + timedelta(minutes=5), **policy)
    assert later.moves == {} and later.status.failure is not None
    assert later.create_revision == OLD


def test_an_unhealthy_canary_rolls_back_when_the_policy_says_so() -> None:
    robots = fleet(5)
    replace(robots, 0, canary=True, revision=NEW, root_status="FAILURE")
    policy = {"canary": {"robots": {"matchLabels": {"c": "y"}}}, "onFailure": "Rollback"}
    decision = decide(robots, **policy)
    assert decision.target == OLD
    assert decision.moves == {"r000": OLD}
    assert decision.status.rolled_back.reason == "HealthGateFailed"
    assert decision.status.rolled_back.from_revision == NEW
    assert "RolloutRolledBack" in [e.reason for e in decision.events]
    # The rollback holds while the spec still asks for the failed revision.
    replace(robots, 0, revision=OLD, root_status=None, ready=True)
    later = decide(robots, previous=decision.status, **policy)
    assert later.target == OLD and later.moves == {} and later.status.complete


def test_a_failure_after_the_rollout_completed_is_not_a_rollout_failure() -> None:
    robots = fleet(3, revision=NEW)
    done = decide(robots)
    assert done.status.complete
    replace(robots, 1, root_status="FAILURE")
    after = decide(robots, previous=done.status, onFailure="Rollback")
    assert after.target == NEW and after.moves == {} and after.status.rolled_back is None


@pytest.mark.parametrize(
    ("interrupt", "tree", "moved"),
    [
        (False, "RUNNING", False),
        (True, "RUNNING", True),
        (False, "SUCCESS", True),
        (False, "FAILURE", True),
        (False, None, True),
    ],
)
def test_the_update_lock_keeps_a_robot_with_a_running_tree(
    interrupt: bool, tree: str | None, moved: bool
) -> None:
    robots = fleet(3)
    replace(robots, 1, root_status=tree)
    decision = decide(robots, maxUnavailable=3, interruptRunningTrees=interrupt)
    assert ("r001" in decision.moves) is moved
    assert {"r000", "r002"} <= set(decision.moves)
    if not moved:
        assert decision.status.counts.locked == 1
        assert decision.status.waiting_for == ["r001"]
        assert not decision.status.complete
        assert "WaitingForRunningTrees" in [e.reason for e in decision.events]


def test_a_locked_robot_updates_once_its_tree_finishes() -> None:
    robots = fleet(2)
    replace(robots, 0, root_status="RUNNING")
    replace(robots, 1, revision=NEW)
    held = decide(robots)
    assert held.moves == {}
    replace(robots, 0, root_status="SUCCESS")
    assert decide(robots, previous=held.status).moves == {"r000": NEW}


def test_offline_robots_are_skipped_by_default_and_do_not_stall_the_fleet() -> None:
    robots = fleet(4)
    replace(robots, 3, online=False, ready=False)
    decision = decide(robots, maxUnavailable=1)
    assert len(decision.moves) == 1 and "r003" not in decision.moves
    assert decision.status.counts.offline == 1
    for index in range(3):
        replace(robots, index, revision=NEW)
    done = decide(robots, previous=decision.status, maxUnavailable=1)
    assert done.status.complete and done.moves == {}
    assert "1 offline robots skipped" in done.status.message
    # Back online, it is updated like any other robot.
    replace(robots, 3, online=True, ready=True)
    assert decide(robots, previous=done.status, maxUnavailable=1).moves == {"r003": NEW}


def test_offline_robots_are_waited_for_when_the_setting_says_wait() -> None:
    robots = fleet(4)
    replace(robots, 3, online=False, ready=False)
    decision = decide(robots, maxUnavailable=2, offlineRobots="Wait")
    assert decision.moves == {}
    assert decision.status.waiting_for == ["r003"]
    assert "WaitingForOfflineRobots" in [e.reason for e in decision.events]
    replace(robots, 3, online=True, ready=True)
    assert len(decide(robots, previous=decision.status, maxUnavailable=2, offlineRobots="Wait").moves) == 2


def test_offline_robots_use_the_budget_when_counted_unavailable() -> None:
    robots = fleet(6)
    replace(robots, 4, online=False, ready=False)
    replace(robots, 5, online=False, ready=False)
    decision = decide(robots, maxUnavailable=3, offlineRobots="CountUnavailable")
    assert len(decision.moves) == 1
    assert not set(decision.moves) & {"r004", "r005"}


def test_paused_rollouts_move_nobody_and_say_so_once() -> None:
    robots = fleet(3)
    started = decide(robots)
    paused = decide(robots, previous=started.status, paused=True)
    assert paused.moves == {} and paused.status.paused
    assert [e.reason for e in paused.events] == ["RolloutPaused"]
    resumed = decide(robots, previous=paused.status)
    assert "RolloutResumed" in [e.reason for e in resumed.events]


def test_undo_returns_every_robot_to_the_previous_revision_within_the_budget() -> None:
    robots = fleet(4, revision=NEW)
    decision = decide(robots, undo_from=NEW, maxUnavailable=2)
    assert decision.target == OLD and len(decision.moves) == 2
    assert set(decision.moves.values()) == {OLD}
    assert decision.status.rolled_back.reason == "Undo"
    # A new revision in the spec ends the rollback.
    newer = plan_rollout(
        RolloutRequest(
            desired="newer00000",
            history=(OLD, NEW, "newer00000"),
            robots=robots,
            policy=RolloutSpec(),
            previous=decision.status,
            now=NOW,
            undo_from=NEW,
        )
    )
    assert newer.target == "newer00000" and newer.status.rolled_back is None


def test_a_first_deployment_has_nothing_to_roll_out_and_no_events_until_ready() -> None:
    robots = [RobotView(robot=f"r{i}", revision=None) for i in range(3)]
    decision = decide(robots, history=(NEW,))
    assert decision.moves == {} and decision.create_revision == NEW
    assert decision.events == []


def test_resuming_clears_the_recorded_failure_and_judges_the_robots_afresh() -> None:
    robots = fleet(4)
    replace(robots, 0, canary=True, revision=NEW, root_status="FAILURE")
    policy = {"canary": {"robots": {"matchLabels": {"c": "y"}}, "holdSeconds": 0}}
    failed = decide(robots, **policy)
    stamp = failed.status.failure.time
    replace(robots, 0, root_status="SUCCESS")
    # Another failure time than the recorded one does not count as acknowledging it.
    assert decide(robots, previous=failed.status, resumed="2020-01-01T00:00:00Z", **policy).moves == {}
    resumed = plan_rollout(
        RolloutRequest(
            desired=NEW,
            history=(OLD, NEW),
            robots=robots,
            policy=RolloutSpec.model_validate(policy),
            previous=failed.status,
            now=NOW,
            resumed=stamp,
        )
    )
    assert resumed.status.failure is None and not resumed.status.paused
    assert resumed.moves
