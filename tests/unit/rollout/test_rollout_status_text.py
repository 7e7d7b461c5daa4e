"""`coral rollout status` text and the `RolloutComplete` condition, from `status.rollout` alone."""

from __future__ import annotations

import pytest
from coral_operator.api.rollout import CanaryStatus, RolledBack, RolloutCounts, RolloutFailure, RolloutStatus
from coral_operator.rollout_control import describe, finished
from coral_operator.status.rollout import evaluate_rollout


def body(rollout: RolloutStatus | None) -> dict:
    status = {"revision": "abc"} | ({"rollout": rollout.to_wire()} if rollout else {})
    return {"metadata": {"name": "patrol"}, "status": status}


def test_status_names_revision_counts_canary_rollback_failure_and_waits() -> None:
    rollout = RolloutStatus(
        revision="new",
        previous_revision="old",
        counts=RolloutCounts(total=10, updated=4, healthy=3, unavailable=1, max_unavailable=1, locked=2),
        canary=CanaryStatus(robots=2, healthy=2, promoted=True),
        rolled_back=RolledBack(from_revision="bad", to_revision="new", reason="HealthGateFailed"),
        failure=RolloutFailure(
            revision="new", message="Revision new failed the health gate on 1 robots (r1)."
        ),
        waiting_for=["r7", "r8"],
        message="3 of 10 robots healthy on revision new.",
    )
    text = describe(body(rollout))
    assert "coralsystem/patrol revision new (previous old)" in text
    assert "3 healthy, 4 updated of 10; 1 unavailable (max 1), 2 locked by running trees" in text
    assert "canary: 2 of 2 healthy, promoted" in text
    assert "rolled back from bad to new (HealthGateFailed)" in text
    assert "failure: Revision new failed the health gate" in text
    assert "waiting for: r7, r8" in text


def test_a_system_without_a_rollout_says_so() -> None:
    assert "no rollout reported yet" in describe(body(None))
    assert not finished(body(None))


@pytest.mark.parametrize(
    ("rollout", "status", "reason"),
    [
        (RolloutStatus(complete=True), "True", "Complete"),
        (
            RolloutStatus(complete=True, rolled_back=RolledBack(from_revision="b", to_revision="a")),
            "True",
            "RolledBack",
        ),
        (RolloutStatus(failure=RolloutFailure(revision="b"), paused=True), "False", "HealthGateFailed"),
        (RolloutStatus(paused=True), "False", "Paused"),
        (
            RolloutStatus(canary=CanaryStatus(robots=1, healthy_since="2026-01-01T00:00:00Z")),
            "False",
            "CanaryHold",
        ),
        (
            RolloutStatus(counts=RolloutCounts(total=3, updated=1, locked=2)),
            "False",
            "WaitingForRunningTrees",
        ),
        (
            RolloutStatus(counts=RolloutCounts(total=3, updated=2, offline=1)),
            "False",
            "WaitingForOfflineRobots",
        ),
        (RolloutStatus(counts=RolloutCounts(total=3, updated=1)), "False", "InProgress"),
    ],
)
def test_the_rollout_condition_says_why_it_is_not_complete(
    rollout: RolloutStatus, status: str, reason: str
) -> None:
    verdict = evaluate_rollout(rollout)
    assert (verdict.status_text, verdict.reason.value) == (status, reason)
    assert verdict.type.value == "RolloutComplete"
