"""`coral rollout status` text and the `RolloutComplete` condition, from `status.rollout` alone."""

from __future__ import annotations

import pytest
from click.testing import CliRunner
from coral_operator.api.rollout import CanaryStatus, RolledBack, RolloutCounts, RolloutFailure, RolloutStatus
from coral_operator.rollout_cli import rollout
from coral_operator.rollout_control import RolloutControl, describe, evaluate_progress, finished
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


def _system(generation: int, observed: int | None, rollout: RolloutStatus | None) -> dict:
    status: dict = {} if observed is None else {"observedGeneration": observed}
    if rollout is not None:
        status["rollout"] = rollout.to_wire()
    return {"metadata": {"name": "patrol", "generation": generation}, "status": status}


@pytest.mark.parametrize(
    ("story", "system", "done", "failed"),
    [
        (
            "a complete report of an older spec is not complete",
            _system(3, 2, RolloutStatus(complete=True)),
            False,
            False,
        ),
        ("a new object without status waits", _system(1, None, None), False, False),
        ("complete at the observed generation", _system(3, 3, RolloutStatus(complete=True)), True, False),
        (
            "a failed health gate fails",
            _system(3, 3, RolloutStatus(failure=RolloutFailure(revision="b", message="m"), paused=True)),
            False,
            True,
        ),
        (
            "a finished rollback fails: the spec's revision does not run",
            _system(
                3,
                3,
                RolloutStatus(complete=True, rolled_back=RolledBack(from_revision="b", to_revision="a")),
            ),
            False,
            True,
        ),
        ("a paused rollout waits", _system(3, 3, RolloutStatus(paused=True)), False, False),
    ],
)
def test_rollout_progress_is_judged_at_the_observed_generation(
    story: str, system: dict, done: bool, failed: bool
) -> None:
    progress = evaluate_progress(system)
    assert (progress.done, progress.failure is not None) == (done, failed), story


def test_status_after_undo_names_the_spec_and_the_target_revision() -> None:
    rollout = RolloutStatus(
        revision="a",
        previous_revision=None,
        history=["a", "b"],
        complete=True,
        rolled_back=RolledBack(from_revision="b", to_revision="a"),
        counts=RolloutCounts(total=2, updated=2, healthy=2),
    )
    text = describe(_system(4, 4, rollout))
    assert "spec revision b" in text and "target revision a; 2 of 2 robots run it" in text
    assert "failed: rolled back from revision b to a" in text


class _Control:
    def __init__(self, bodies: list[dict]) -> None:
        self.bodies = bodies

    def read(self, name: str) -> dict:
        return self.bodies.pop(0) if len(self.bodies) > 1 else self.bodies[0]


@pytest.mark.parametrize(
    ("system", "args", "exit_code"),
    [
        (_system(2, 2, RolloutStatus(complete=True)), [], 0),
        (_system(2, 2, RolloutStatus(failure=RolloutFailure(revision="b", message="x"))), [], 1),
        (
            _system(
                2, 2, RolloutStatus(complete=True, rolled_back=RolledBack(from_revision="b", to_revision="a"))
            ),
            [],
            1,
        ),
        (_system(2, 1, RolloutStatus(complete=True)), ["--watch", "--timeout", "0"], 1),
        (_system(2, 1, RolloutStatus(complete=True)), [], 0),
    ],
    ids=["complete", "gate-failed", "rolled-back", "timeout-on-unobserved-spec", "no-watch-shows-and-exits"],
)
def test_rollout_status_exit_codes(
    monkeypatch: pytest.MonkeyPatch, system: dict, args: list[str], exit_code: int
) -> None:
    monkeypatch.setattr(
        RolloutControl, "from_kubeconfig", classmethod(lambda cls, namespace: _Control([system]))
    )
    result = CliRunner().invoke(rollout, ["status", "patrol", *args])
    assert result.exit_code == exit_code, result.output


def test_a_refused_spec_fails_rollout_status_even_with_an_old_complete_rollout() -> None:
    system = _system(3, 3, RolloutStatus(complete=True))
    system["status"]["conditions"] = [
        {
            "type": "Stalled",
            "status": "True",
            "reason": "InvalidTree",
            "message": "t.xml:3: bad",
            "observedGeneration": 3,
        }
    ]
    progress = evaluate_progress(system)
    assert not progress.done and progress.failure and "t.xml:3: bad" in progress.failure
