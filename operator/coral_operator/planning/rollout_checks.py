"""The checks one rollout pass is made of, each a small pure function with its reason.

`planning.rollout.plan_rollout` runs them in this order, each on what the previous ones found:

1. `check_target`: which revision robots move to (the newest, or an earlier one when rolled back).
2. `check_gate`: whether one robot on that revision passes or fails the health gate.
3. `check_failure`: whether a failed gate pauses the rollout or rolls the fleet back.
4. `check_canary`: whether the canaries have held healthy long enough for the rest to follow.
5. `check_lock`: whether a robot's running tree holds it at its revision (the update lock).
6. `check_offline`: how offline robots count (skipped, waited for, counted unavailable).
7. `check_hold`: whether anything keeps every robot where it is this pass.
8. `plan_wave`: which robots move now within `maxUnavailable`.
9. `check_complete`: whether the rollout is done.

Every result carries a `reason`, a CamelCase word saying which rule decided, so a table test can
show inputs, decision and reason side by side. Nothing here keeps state between passes; what must
outlive a pass (the canary clock, a recorded failure, a rollback) travels in `status.rollout`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta

from coral_operator.api.rollout import MAX_NAMED, CanaryStatus, RolledBack, RolloutFailure, RolloutStatus
from coral_operator.api.system import RolloutSpec
from coral_operator.planning import rollout_report
from coral_operator.planning.pull_state import Pull

FAILURE = "FAILURE"
RUNNING = "RUNNING"


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
    root_status: str | None = None
    """Root status the executor reported (RUNNING, SUCCESS, FAILURE, ...)."""
    stalled: bool = False
    """The instance is Stalled (a component failed, or startup timed out with `Block`)."""
    canary: bool = False
    """The robot matches `spec.rollout.canary.robots`."""
    pulls: Mapping[str, Pull] = field(default_factory=dict)
    """Revision -> where the robot's pull of its images stands (`spec.rollout.prePull` only)."""


def revision_before(history: Sequence[str], revision: str) -> str | None:
    """The revision that preceded `revision` in the history (oldest first), if any."""
    if revision not in history:
        return history[-1] if history else None
    index = list(history).index(revision)
    return history[index - 1] if index > 0 else None


def names_of(robots: Sequence[RobotView]) -> list[str]:
    """The first robot names, sorted, as few as a status list may hold."""
    return sorted(r.robot for r in robots)[:MAX_NAMED]


def stamp(moment: datetime) -> str:
    """`moment` as RFC 3339 in whole seconds, as status fields carry it."""
    return moment.strftime("%Y-%m-%dT%H:%M:%SZ")


def parse_stamp(moment: str | None) -> datetime | None:
    """A status field's RFC 3339 time, or None when unset."""
    if not moment:
        return None
    return datetime.fromisoformat(moment.replace("Z", "+00:00"))


@dataclass(frozen=True)
class Target:
    """The revision robots move to this pass, and the rollback in force."""

    revision: str
    rolled_back: RolledBack | None
    reason: str
    """`Newest`, `StillRolledBack`, `Undo` or `NothingToUndo`."""


def check_target(
    desired: str, history: Sequence[str], previous: RolloutStatus | None, undo_from: str | None
) -> Target:
    """The spec's newest revision, unless the fleet is rolled back from it.

    A rollback (asked for by `coral rollout undo`, or by a failed gate with `onFailure: Rollback`)
    lasts while the spec still asks for the revision rolled back from; a newer revision ends it.
    """
    earlier = previous.rolled_back if previous else None
    if earlier is not None and earlier.from_revision == desired and earlier.to_revision in history:
        return Target(earlier.to_revision, earlier, "StillRolledBack")
    if undo_from == desired:
        before = revision_before(history, desired)
        if before is None:
            return Target(desired, None, "NothingToUndo")
        return Target(before, RolledBack(from_revision=desired, to_revision=before, reason="Undo"), "Undo")
    return Target(desired, None, "Newest")


@dataclass(frozen=True)
class Gate:
    """One robot measured against the health gate."""

    passed: bool
    """On the target, instance Ready, tree not failed: counts as healthy."""
    failed: bool
    """Online, on the target and broken: can fail the rollout."""
    reason: str
    """`NotOnTarget`, `TreeFailed`, `Stalled`, `Healthy`, `Offline` or `NotReady`."""


def check_gate(robot: RobotView, target: str) -> Gate:
    """The health gate: a robot on the target passes when its instance is Ready and its tree has not
    returned FAILURE; it fails when its instance is Stalled or its Ready tree returned FAILURE. An
    offline robot is never failed: its status is stale."""
    if robot.revision != target:
        return Gate(False, False, "NotOnTarget")
    tree_failed = robot.ready and robot.root_status == FAILURE
    passed = robot.ready and robot.root_status != FAILURE
    failed = robot.online and (robot.stalled or tree_failed)
    if failed:
        return Gate(passed, True, "TreeFailed" if tree_failed else "Stalled")
    if passed:
        return Gate(True, False, "Healthy")
    return Gate(False, False, "NotReady" if robot.online else "Offline")


@dataclass(frozen=True)
class Failure:
    """The health-gate verdict over the fleet, and where it leaves the target."""

    target: str
    """The revision robots move to, after a rollback this pass decided."""
    previous_revision: str | None
    """The revision before `target` in the history."""
    rolled_back: RolledBack | None
    failure: RolloutFailure | None
    """The failure that pauses the rollout (recorded earlier, or found now)."""
    failing: tuple[RobotView, ...]
    """Robots failing the gate of the target this pass started with."""
    event: rollout_report.RolloutEvent | None
    reason: str
    """`FailedRollBack`, `FailedPause`, `RollingBack`, `FailureRecorded`, `NoRobotFailing`,
    `NotUnderWay` or `NowhereToGoBack`."""


def check_failure(
    *,
    target: Target,
    robots: Sequence[RobotView],
    history: Sequence[str],
    previous: RolloutStatus | None,
    resumed: str | None,
    on_failure: str,
    now: datetime,
) -> Failure:
    """Judge the health gate while a rollout is under way and there is somewhere to go back to.

    A failure recorded on `status.rollout` stays until `coral rollout resume` names its time; the
    robots are then judged afresh, so a robot still failing fails the rollout again. A new failure
    pauses the rollout (`onFailure: Pause`) or rolls the fleet back (`onFailure: Rollback`).
    """
    revision, rolled_back = target.revision, target.rolled_back
    before = revision_before(history, revision)
    same_target = previous is not None and previous.revision == revision
    failing = tuple(r for r in robots if check_gate(r, revision).failed)
    failure = previous.failure if previous is not None else None
    if failure is not None and failure.revision != revision:
        failure = None
    if failure is not None and resumed is not None and resumed == failure.time:
        failure = None
    under_way = any(r.revision != revision for r in robots) or (
        same_target and previous is not None and not previous.complete
    )
    if failure is None and under_way and failing and before is not None and rolled_back is None:
        names = names_of(failing)
        message = (
            f"Revision {revision} failed the health gate on {len(failing)} robots "
            f"({rollout_report.shown(names, len(failing))})."
        )
        if on_failure == "Rollback":
            return Failure(
                target=before,
                previous_revision=revision_before(history, before),
                rolled_back=RolledBack(from_revision=revision, to_revision=before, reason="HealthGateFailed"),
                failure=None,
                failing=failing,
                event=rollout_report.RolloutEvent(
                    "RolloutRolledBack", f"{message} Rolling back to revision {before}.", True
                ),
                reason="FailedRollBack",
            )
        return Failure(
            target=revision,
            previous_revision=before,
            rolled_back=None,
            failure=RolloutFailure(revision=revision, robots=names, message=message, time=stamp(now)),
            failing=failing,
            event=rollout_report.RolloutEvent("RolloutFailed", f"{message} The rollout is paused.", True),
            reason="FailedPause",
        )
    event = None
    if rolled_back is not None and (previous is None or previous.rolled_back != rolled_back):
        event = rollout_report.RolloutEvent(
            "RolloutRolledBack",
            f"Rolling back from revision {rolled_back.from_revision} to {rolled_back.to_revision}.",
            True,
        )
    if rolled_back is not None:
        reason = "RollingBack"
    elif failure is not None:
        reason = "FailureRecorded"
    elif not failing:
        reason = "NoRobotFailing"
    elif not under_way:
        reason = "NotUnderWay"
    else:
        reason = "NowhereToGoBack"
    return Failure(revision, before, rolled_back, failure, failing, event, reason)


@dataclass(frozen=True)
class Canary:
    """Where the canaries stand."""

    status: CanaryStatus | None
    """`status.rollout.canary`; None without `spec.rollout.canary`."""
    done: bool
    """The rest of the fleet may follow."""
    wake_at: datetime | None
    """When the hold ends, to look again even if nothing changes."""
    robots: tuple[RobotView, ...]
    """Canaries still to consider (online ones, or all with `offlineRobots: Wait`)."""
    event: rollout_report.RolloutEvent | None
    reason: str
    """`NoCanary`, `NoCanaryRobots`, `AlreadyPromoted`, `RollingBack`, `NotHealthy`, `Holding` or
    `Promoted`."""


def check_canary(
    *,
    policy: RolloutSpec,
    robots: Sequence[RobotView],
    target: str,
    previous: CanaryStatus | None,
    rolled_back: RolledBack | None,
    now: datetime,
) -> Canary:
    """Canaries move first and must pass the health gate for `holdSeconds` before any other robot.

    `previous` is the canary status last written for the same target. Going back to a revision that
    ran before (a rollback) needs no canary.
    """
    if policy.canary is None:
        return Canary(None, True, None, (), None, "NoCanary")
    canaries = [r for r in robots if r.canary]
    considered = tuple(r for r in canaries if r.online or policy.offline_robots == "Wait")
    status = CanaryStatus(
        robots=len(canaries),
        updated=sum(1 for r in canaries if r.revision == target),
        healthy=sum(1 for r in canaries if check_gate(r, target).passed),
    )
    done, wake_at = True, None
    if not canaries or (previous is not None and previous.promoted):
        status.promoted = True
        reason = "NoCanaryRobots" if not canaries else "AlreadyPromoted"
    elif not considered or not all(check_gate(r, target).passed for r in considered):
        done, reason = False, "NotHealthy"
    else:
        since = (parse_stamp(previous.healthy_since) if previous else None) or now
        status.healthy_since = stamp(since)
        due = since + timedelta(seconds=policy.canary.hold_seconds)
        if now >= due:
            status.promoted, reason = True, "Promoted"
        else:
            done, wake_at, reason = False, due, "Holding"
    if rolled_back is not None:
        status.promoted, done, wake_at, reason = True, True, None, "RollingBack"
    event = None
    newly_promoted = status.promoted and not (previous is not None and previous.promoted)
    if newly_promoted and status.robots and rolled_back is None:
        event = rollout_report.RolloutEvent(
            "CanaryPromoted",
            f"{status.healthy} canary robots stayed healthy on revision {target}; "
            "the rest of the fleet follows.",
        )
    return Canary(status, done, wake_at, considered, event, reason)


@dataclass(frozen=True)
class Lock:
    """The update lock of one robot still to update."""

    held: bool
    """The robot stays at its revision this pass."""
    reason: str
    """`Offline`, `TreeRunning`, `InterruptAllowed` or `TreeNotRunning`."""


def check_lock(robot: RobotView, interrupt_running_trees: bool) -> Lock:
    """A robot whose tree is RUNNING is not moved unless `interruptRunningTrees` is set."""
    if not robot.online:
        return Lock(False, "Offline")
    if robot.root_status != RUNNING:
        return Lock(False, "TreeNotRunning")
    if interrupt_running_trees:
        return Lock(False, "InterruptAllowed")
    return Lock(True, "TreeRunning")


@dataclass(frozen=True)
class Offline:
    """How the offline robots count this pass."""

    pending: tuple[RobotView, ...]
    """Offline robots not yet on the target."""
    waiting: bool
    """`offlineRobots: Wait` and one of them still needs the update: nobody moves."""
    unavailable: int
    """Offline robots counted against `maxUnavailable` (`CountUnavailable` only)."""
    required: tuple[RobotView, ...]
    """Robots the rollout must bring onto the target before it is complete."""
    reason: str
    """`AllOnline`, `OfflineSkipped`, `WaitingForOfflineRobots`, `OfflineUpToDate` or
    `OfflineCountedUnavailable`."""


def check_offline(robots: Sequence[RobotView], target: str, mode: str) -> Offline:
    """Offline robots (Node not Ready) are never moved. `Skip` leaves them out of the budget and of
    completion, `Wait` moves nobody else while one still needs the update, `CountUnavailable`
    counts them against `maxUnavailable`."""
    offline = [r for r in robots if not r.online]
    pending = tuple(r for r in offline if r.revision != target)
    required = tuple(r for r in robots if r.online or mode != "Skip")
    unavailable = len(offline) if mode == "CountUnavailable" else 0
    waiting = mode == "Wait" and bool(pending)
    if not offline:
        reason = "AllOnline"
    elif mode == "Skip":
        reason = "OfflineSkipped"
    elif mode == "Wait":
        reason = "WaitingForOfflineRobots" if waiting else "OfflineUpToDate"
    else:
        reason = "OfflineCountedUnavailable"
    return Offline(pending, waiting, unavailable, required, reason)


@dataclass(frozen=True)
class Hold:
    """Whether every robot stays where it is this pass."""

    held: bool
    reason: str
    """`Paused`, `FailedHealthGate`, `WaitingForOfflineRobots` or `Proceed`."""


def check_hold(*, paused: bool, failure: RolloutFailure | None, waiting_offline: bool) -> Hold:
    """A paused rollout (by the spec or by a recorded failure) moves no robot; neither does one
    waiting for offline robots."""
    if paused:
        return Hold(True, "Paused")
    if failure is not None:
        return Hold(True, "FailedHealthGate")
    if waiting_offline:
        return Hold(True, "WaitingForOfflineRobots")
    return Hold(False, "Proceed")


@dataclass(frozen=True)
class Wave:
    """The robots moved this pass."""

    moves: dict[str, str] = field(default_factory=dict)
    """Robot name -> the revision it moves to."""
    reason: str = "NothingToMove"
    """`NothingToMove`, `AllMoved` or `BudgetSpent` (some robots wait for the next wave)."""


def plan_wave(
    *, candidates: Sequence[RobotView], target: str, max_unavailable: int, unavailable: int
) -> Wave:
    """At most `max_unavailable` robots are unavailable at once; moving a robot that is already
    unavailable costs nothing, as a DaemonSet does. Robots already unavailable move first, then
    canaries, then by name.

    Args:
        candidates: robots that may move this pass (online, not locked, in the current pool).
        unavailable: robots counted unavailable already.
    """
    eligible = sorted(
        (r for r in candidates if r.revision != target), key=lambda r: (r.ready, not r.canary, r.robot)
    )
    if not eligible:
        return Wave()
    budget = max_unavailable - unavailable
    moves: dict[str, str] = {}
    for robot in eligible:
        if not robot.ready:
            moves[robot.robot] = target
        elif budget > 0:
            moves[robot.robot] = target
            budget -= 1
    return Wave(moves, "AllMoved" if len(moves) == len(eligible) else "BudgetSpent")


@dataclass(frozen=True)
class Completion:
    """Whether the rollout is done."""

    complete: bool
    reason: str
    """`RobotsMoving`, `NotAllHealthy` or `Complete`."""


def check_complete(*, required: Sequence[RobotView], target: str, moves: dict[str, str]) -> Completion:
    """Done when every robot that must be updated passes the health gate on the target and nobody
    moves this pass."""
    if moves:
        return Completion(False, "RobotsMoving")
    if not all(check_gate(r, target).passed for r in required):
        return Completion(False, "NotAllHealthy")
    return Completion(True, "Complete")
