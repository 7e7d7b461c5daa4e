"""Fleet rollout decisions: which robots move to which revision now (docs/architecture.md, "Rollouts").

Pure and level-based: from the newest revision, the revision history, what every robot runs and
how it is doing, the rollout policy and the previous `status.rollout`, decide the moves of this
pass, the new `status.rollout`, the Events worth posting and when to look again. Nothing here
remembers anything between passes except through `status.rollout`, so an operator restarted
mid-rollout makes the same decisions from the same observations and never exceeds
`maxUnavailable`. Called by the system handler between `planning.instances.build_instance` (one
template per revision) and `planning.instances.plan_instances`.

Rules, in the order they apply:

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
- Offline robots (Node not Ready) are never moved: `Skip` leaves them out of the budget and of
  completion, `Wait` moves nobody else while one still needs the update, `CountUnavailable`
  counts them against `maxUnavailable`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta

from coral_operator.api.rollout import (
    MAX_NAMED,
    CanaryStatus,
    RolledBack,
    RolloutCounts,
    RolloutFailure,
    RolloutStatus,
)
from coral_operator.api.system import RolloutSpec
from coral_operator.planning import rollout_report

RolloutEvent = rollout_report.RolloutEvent
_PERCENT = re.compile(r"^(\d{1,3})%$")
FIELD = "spec.rollout.maxUnavailable"


@dataclass(frozen=True)
class RobotView:
    """One matched robot as the rollout sees it."""

    robot: str
    revision: str | None
    """Revision its CoralInstance runs; None before the instance exists."""
    ready: bool = False
    """The instance is Ready at its current generation."""
    online: bool = True
    """The robot's Node is Ready."""
    tree_root: str | None = None
    """Root status the executor reported (RUNNING, SUCCESS, FAILURE, ...)."""
    stalled: bool = False
    """The instance is Stalled (a component failed, or startup timed out with `Block`)."""
    canary: bool = False
    """The robot matches `spec.rollout.canary.robots`."""


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


def resolve_max_unavailable(value: int | str, total: int) -> int:
    """`maxUnavailable` as a count of robots: at least 1; a percentage rounds up, as for DaemonSets.

    Raises:
        ValueError: the value is neither a non-negative count nor a percentage; names the field.
    """
    if isinstance(value, bool):
        raise ValueError(f"{FIELD}: expected a count or a percentage like '10%', got {value!r}")
    if isinstance(value, int):
        if value < 0:
            raise ValueError(f"{FIELD}: must not be negative, got {value}")
        return max(1, value)
    match = _PERCENT.match(value.strip())
    if match is None:
        if value.strip().isdigit():
            return max(1, int(value.strip()))
        raise ValueError(f"{FIELD}: expected a count or a percentage like '10%', got {value!r}")
    percent = int(match.group(1))
    if percent > 100:
        raise ValueError(f"{FIELD}: a percentage must be at most 100%, got {value!r}")
    return max(1, math.ceil(total * percent / 100))


def revision_before(history: Sequence[str], revision: str) -> str | None:
    """The revision that preceded `revision` in the history (oldest first), if any."""
    if revision not in history:
        return history[-1] if history else None
    index = list(history).index(revision)
    return history[index - 1] if index > 0 else None


def resolve_target(
    desired: str, history: Sequence[str], previous: RolloutStatus | None, undo_from: str | None
) -> tuple[str, RolledBack | None]:
    """The revision to move robots to, and the rollback in force (if any)."""
    earlier = previous.rolled_back if previous else None
    if earlier is not None and earlier.from_revision == desired and earlier.to_revision in history:
        return earlier.to_revision, earlier
    if undo_from == desired:
        before = revision_before(history, desired)
        if before is not None:
            return before, RolledBack(from_revision=desired, to_revision=before, reason="Undo")
    return desired, None


def _names(robots: Sequence[RobotView]) -> list[str]:
    return sorted(r.robot for r in robots)[:MAX_NAMED]


def passes_gate(robot: RobotView, target: str) -> bool:
    """On the target, instance Ready, tree not failed."""
    return robot.revision == target and robot.ready and robot.tree_root != "FAILURE"


def fails_gate(robot: RobotView, target: str) -> bool:
    """On the target and broken: instance Stalled, or Ready with a tree that returned FAILURE."""
    return (
        robot.online
        and robot.revision == target
        and (robot.stalled or (robot.ready and robot.tree_root == "FAILURE"))
    )


def _parse(moment: str | None) -> datetime | None:
    if not moment:
        return None
    return datetime.fromisoformat(moment.replace("Z", "+00:00"))


def _stamp(moment: datetime) -> str:
    return moment.strftime("%Y-%m-%dT%H:%M:%SZ")


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


def _canary(
    request: RolloutRequest, target: str, counted: Sequence[RobotView], same_target: bool
) -> tuple[CanaryStatus | None, bool, datetime | None, list[RobotView]]:
    """(canary status, canaries done, wake time, canary robots still to consider)."""
    policy = request.policy
    if policy.canary is None:
        return None, True, None, []
    canaries = [r for r in counted if r.canary]
    considered = [r for r in canaries if r.online or request.policy.offline_robots == "Wait"]
    previous = request.previous.canary if request.previous and same_target else None
    status = CanaryStatus(
        robots=len(canaries),
        updated=sum(1 for r in canaries if r.revision == target),
        healthy=sum(1 for r in canaries if passes_gate(r, target)),
    )
    if not canaries or (previous is not None and previous.promoted):
        status.promoted = True
        return status, True, None, considered
    if not considered or not all(passes_gate(r, target) for r in considered):
        return status, False, None, considered
    since = _parse(previous.healthy_since) if previous else None
    since = since or request.now
    status.healthy_since = _stamp(since)
    due = since + timedelta(seconds=policy.canary.hold_seconds)
    if request.now >= due:
        status.promoted = True
        return status, True, None, considered
    return status, False, due, considered


def plan_rollout(request: RolloutRequest) -> RolloutDecision:
    """Decide this pass of the rollout; see the module docstring for the rules.

    Raises:
        ValueError: `maxUnavailable` is malformed (the message names the field).
    """
    policy = request.policy
    target, rolled_back = resolve_target(
        request.desired, request.history, request.previous, request.undo_from
    )
    previous = request.previous
    same_target = previous is not None and previous.revision == target
    counted = [r for r in request.robots if r.revision is not None]
    max_unavailable = resolve_max_unavailable(policy.max_unavailable, len(counted))
    before = revision_before(request.history, target)
    events: list[rollout_report.RolloutEvent] = []

    # A failure is judged only while a rollout is under way and there is somewhere to go back to.
    under_way = any(r.revision != target for r in counted) or (same_target and not previous.complete)
    failure = (
        previous.failure if previous and previous.failure and previous.failure.revision == target else None
    )
    if failure is not None and request.resumed is not None and request.resumed == failure.time:
        # Resumed by a human: judge the robots afresh (a robot still failing fails it again).
        failure = None
    failing = [r for r in counted if fails_gate(r, target)]
    if failure is None and under_way and failing and before is not None and rolled_back is None:
        names = _names(failing)
        message = (
            f"Revision {target} failed the health gate on {len(failing)} robots "
            f"({rollout_report.shown(names, len(failing))})."
        )
        if policy.on_failure == "Rollback":
            rolled_back = RolledBack(from_revision=target, to_revision=before, reason="HealthGateFailed")
            events.append(
                rollout_report.RolloutEvent(
                    "RolloutRolledBack", f"{message} Rolling back to revision {before}.", True
                )
            )
            target, same_target = before, previous is not None and previous.revision == before
            before = revision_before(request.history, target)
        else:
            failure = RolloutFailure(revision=target, robots=names, message=message, time=_stamp(request.now))
            events.append(
                rollout_report.RolloutEvent("RolloutFailed", f"{message} The rollout is paused.", True)
            )
    elif rolled_back is not None and (previous is None or previous.rolled_back != rolled_back):
        events.append(
            rollout_report.RolloutEvent(
                "RolloutRolledBack",
                f"Rolling back from revision {rolled_back.from_revision} to {rolled_back.to_revision}.",
                True,
            )
        )

    canary, canaries_done, wake_at, canaries = _canary(request, target, counted, same_target)
    if rolled_back is not None and canary is not None:
        # Going back to a revision that ran before needs no canary.
        canary.promoted, canaries_done, wake_at = True, True, None
    if (
        canary is not None
        and canary.promoted
        and not (previous and same_target and previous.canary and previous.canary.promoted)
    ):
        if canary.robots and rolled_back is None:
            events.append(
                rollout_report.RolloutEvent(
                    "CanaryPromoted",
                    f"{canary.healthy} canary robots stayed healthy on revision {target}; "
                    "the rest of the fleet follows.",
                )
            )

    mode = policy.offline_robots
    pending = [r for r in counted if r.revision != target]
    offline_pending = [r for r in pending if not r.online]
    locked = [
        r for r in pending if r.online and r.tree_root == "RUNNING" and not policy.interrupt_running_trees
    ]
    unavailable = sum(1 for r in counted if r.online and not r.ready)
    if mode == "CountUnavailable":
        unavailable += sum(1 for r in counted if not r.online)

    paused = policy.paused or failure is not None
    waiting_offline = mode == "Wait" and bool(offline_pending)
    moves: dict[str, str] = {}
    if not paused and not waiting_offline:
        pool = canaries if not canaries_done else counted
        eligible = [r for r in pool if r.revision != target and r.online and r not in locked]
        # Robots already unavailable move first and for free; then canaries; then by name.
        eligible.sort(key=lambda r: (r.ready, not r.canary, r.robot))
        budget = max_unavailable - unavailable
        for robot in eligible:
            if not robot.ready:
                moves[robot.robot] = target
            elif budget > 0:
                moves[robot.robot] = target
                budget -= 1

    required = [r for r in counted if r.online or mode != "Skip"]
    healthy = sum(1 for r in counted if passes_gate(r, target))
    complete = all(passes_gate(r, target) for r in required) and not moves
    counts = RolloutCounts(
        total=len(counted),
        updated=sum(1 for r in counted if r.revision == target),
        healthy=healthy,
        unavailable=unavailable + sum(1 for name in moves if _was_ready(counted, name)),
        max_unavailable=max_unavailable,
        locked=len(locked),
        offline=len(offline_pending),
        failed=len(failing) if rolled_back is None or rolled_back.from_revision != target else 0,
    )
    waiting = locked + offline_pending
    status = RolloutStatus(
        revision=target,
        previous_revision=before,
        history=list(request.history)[-32:],
        complete=complete,
        paused=paused,
        counts=counts,
        canary=canary,
        failure=failure,
        rolled_back=rolled_back,
        waiting_for=_names(waiting),
        message=rollout_report.build_message(
            target,
            counts,
            complete,
            policy.paused,
            failure,
            rolled_back,
            canary,
            canaries_done,
            mode,
            sorted(r.robot for r in offline_pending),
            sorted(r.robot for r in locked),
        ),
    )
    events.extend(
        rollout_report.build_events(
            previous,
            status,
            moves,
            sorted(r.robot for r in locked),
            sorted(r.robot for r in offline_pending),
            mode,
        )
    )
    create_revision = before if failure is not None and before is not None else target
    return RolloutDecision(
        target=target,
        create_revision=create_revision,
        moves=moves,
        status=status,
        events=events,
        wake_at=wake_at,
    )


def _was_ready(robots: Sequence[RobotView], name: str) -> bool:
    return any(r.robot == name and r.ready for r in robots)
