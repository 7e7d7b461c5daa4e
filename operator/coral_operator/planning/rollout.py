"""Fleet rollout decisions: which robots move to which revision now (docs/architecture.md, "Rollouts").

Pure and level-based: from the newest revision, the revision history, what every robot runs and
how it is doing, the rollout policy and the previous `status.rollout`, decide the moves of this
pass, the new `status.rollout`, the Events worth posting and when to look again. Nothing here
remembers anything between passes except through `status.rollout`, so an operator restarted
mid-rollout makes the same decisions from the same observations and never exceeds
`maxUnavailable`. Called by the system handler between `planning.instances.build_instance` (one
template per revision) and `planning.instances.plan_instances`.

The rules, each a named check in `planning.rollout_checks` with its own table test, in the order
they apply:

- Target: the spec's newest revision, unless the fleet is rolled back from it (`coral rollout undo`
  or a failed health gate with `onFailure: Rollback`): then the revision before it.
- Health gate: a robot on the target passes when its instance is Ready and its tree has not
  returned FAILURE; it fails when its instance is Stalled or its Ready tree reports FAILURE.
- A failure while the rollout is under way pauses it (`onFailure: Pause`) or rolls the fleet back
  (`onFailure: Rollback`); a paused rollout moves no robot.
- Canaries move first and must pass the health gate for `holdSeconds` before any other robot moves.
- At most `maxUnavailable` robots are unavailable (instance not Ready) at once; moving a robot that
  is already unavailable costs nothing, as a DaemonSet does.
- Update lock: a robot whose tree is RUNNING is not moved unless `interruptRunningTrees` is set.
- Images before the wave (`prePull`): a robot moves only once its runtime has the target's images;
  with `BeforeRollout`, nobody moves until every online robot to move pulled or failed, or the
  deadline passed (`planning.prepull`).
- Offline robots (Node not Ready) are never moved: `Skip` leaves them out of the budget and of
  completion, `Wait` moves nobody else while one still needs the update, `CountUnavailable`
  counts them against `maxUnavailable`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime

from coral_operator.api.rollout import RolledBack, RolloutCounts, RolloutStatus
from coral_operator.api.system import RolloutSpec
from coral_operator.planning import prepull, rollout_checks, rollout_report
from coral_operator.planning.pull_state import Pull
from coral_operator.planning.rollout_checks import RobotView

RolloutEvent = rollout_report.RolloutEvent
__all__ = ["RobotView", "RolloutDecision", "RolloutRequest", "plan_rollout"]


@dataclass
class RolloutDecision:
    """What to do in this pass."""

    target: str
    """The revision robots are moved to."""
    create_revision: str
    """The revision a robot without an instance gets."""
    moves: dict[str, str] = field(default_factory=dict)
    """Robot name -> revision to move it to now."""
    status: RolloutStatus = field(default_factory=RolloutStatus)
    events: list[rollout_report.RolloutEvent] = field(default_factory=list)
    wake_at: datetime | None = None
    """When the decision should be made again even if nothing changes (the canary hold ends)."""
    pulls: list[str] = field(default_factory=list)
    """Robots that must pull the target's images (`spec.rollout.prePull`); an offline one's kubelet
    pulls once it is back."""


@dataclass(frozen=True)
class RolloutRequest:
    """Everything one rollout decision is made from."""

    desired: str
    """The spec's newest revision."""
    history: Sequence[str]
    """Known revisions, oldest first; contains `desired`."""
    robots: Sequence[RobotView]
    policy: RolloutSpec
    previous: RolloutStatus | None
    """`status.rollout` as last written."""
    now: datetime
    undo_from: str | None = None
    """Set by `coral rollout undo`: roll back from this revision."""
    resumed: str | None = None
    """Set by `coral rollout resume`: the time of the recorded failure to clear."""


def plan_rollout(request: RolloutRequest) -> RolloutDecision:
    """Decide this pass of the rollout by running the checks of `planning.rollout_checks` in order.

    Raises:
        ValueError: `maxUnavailable` is malformed (the message names the field).
    """
    policy, previous = request.policy, request.previous
    counted = [r for r in request.robots if r.revision is not None]
    max_unavailable = request.policy.unavailable_budget().resolve(len(counted))
    gate = rollout_checks.check_failure(
        target=rollout_checks.check_target(request.desired, request.history, previous, request.undo_from),
        robots=counted,
        history=request.history,
        previous=previous,
        resumed=request.resumed,
        on_failure=policy.on_failure,
        now=request.now,
    )
    target, rolled_back, failure = gate.target, gate.rolled_back, gate.failure
    same_target = previous is not None and previous.revision == target
    canary = rollout_checks.check_canary(
        policy=policy,
        robots=counted,
        target=target,
        previous=previous.canary if previous is not None and same_target else None,
        rolled_back=rolled_back,
        now=request.now,
    )
    offline = rollout_checks.check_offline(counted, target, policy.offline_robots)
    locked = [
        r
        for r in counted
        if r.revision != target and rollout_checks.check_lock(r, policy.interrupt_running_trees).held
    ]
    unavailable = sum(1 for r in counted if r.online and not r.ready) + offline.unavailable
    hold = rollout_checks.check_hold(paused=policy.paused, failure=failure, waiting_offline=offline.waiting)
    pulling = [r for r in counted if r.revision != target]
    images = (
        None
        if policy.pre_pull is None
        else prepull.check_pre_pull(
            spec=policy.pre_pull,
            robots=[prepull.PullingRobot(r.robot, r.online, r.pulls.get(target, Pull())) for r in pulling],
            target=target,
            previous=previous.pre_pull if previous is not None else None,
            now=request.now,
        )
    )
    moves: dict[str, str] = {}
    if not hold.held and not (images is not None and images.held):
        pool = counted if canary.done else canary.robots
        moves = rollout_checks.plan_wave(
            candidates=[
                r
                for r in pool
                if r.online and r not in locked and (images is None or r.robot in images.may_move)
            ],
            target=target,
            max_unavailable=max_unavailable,
            unavailable=unavailable,
        ).moves
    completion = rollout_checks.check_complete(required=offline.required, target=target, moves=moves)
    counts = RolloutCounts(
        total=len(counted),
        updated=sum(1 for r in counted if r.revision == target),
        healthy=sum(1 for r in counted if rollout_checks.check_gate(r, target).passed),
        unavailable=unavailable + sum(1 for r in counted if r.robot in moves and r.ready),
        max_unavailable=max_unavailable,
        locked=len(locked),
        offline=len(offline.pending),
        failed=_failed(gate, rolled_back, target),
    )
    offline_names = sorted(r.robot for r in offline.pending)
    locked_names = sorted(r.robot for r in locked)
    status = RolloutStatus(
        revision=target,
        previous_revision=gate.previous_revision,
        history=list(request.history)[-32:],
        complete=completion.complete,
        paused=policy.paused or failure is not None,
        counts=counts,
        canary=canary.status,
        failure=failure,
        rolled_back=rolled_back,
        waiting_for=rollout_checks.names_of(locked + list(offline.pending)),
        pre_pull=images.status if images is not None else None,
        message=rollout_report.build_message(
            target,
            counts,
            completion.complete,
            policy.paused,
            failure,
            rolled_back,
            canary.status,
            canary.done,
            policy.offline_robots,
            offline_names,
            locked_names,
            images.status if images is not None else None,
        ),
    )
    events = [event for event in (gate.event, canary.event) if event is not None]
    events.extend(
        rollout_report.build_events(
            previous, status, moves, locked_names, offline_names, policy.offline_robots
        )
    )
    wakes = [w for w in (canary.wake_at, images.wake_at if images is not None else None) if w is not None]
    before = gate.previous_revision
    return RolloutDecision(
        target=target,
        create_revision=before if failure is not None and before is not None else target,
        moves=moves,
        status=status,
        events=events,
        wake_at=min(wakes, default=None),
        pulls=sorted(r.robot for r in pulling) if images is not None else [],
    )


def _failed(gate: rollout_checks.Failure, rolled_back: RolledBack | None, target: str) -> int:
    # Robots failing the revision the fleet is leaving are not failures of the rollout back.
    return len(gate.failing) if rolled_back is None or rolled_back.from_revision != target else 0
