"""What a rollout pass says: the one-sentence `status.rollout.message` and the Events worth posting.

Events mark transitions only (started, a quarter of the fleet further, paused, resumed, waiting,
failed, rolled back, complete), compared with the previous `status.rollout`, so a rollout over a
thousand robots posts a handful of Events, not one per pass. Pure; called by `planning.rollout`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from coral_operator.api.rollout import (
    MAX_NAMED,
    CanaryStatus,
    PrePullStatus,
    RolledBack,
    RolloutCounts,
    RolloutFailure,
    RolloutStatus,
)


@dataclass(frozen=True)
class RolloutEvent:
    """An Event to post on the CoralSystem."""

    reason: str
    message: str
    warning: bool = False


def shown(names: Sequence[str], total: int) -> str:
    more = f" and {total - len(names)} more" if total > len(names) else ""
    return ", ".join(names) + more


def build_message(
    target: str,
    counts: RolloutCounts,
    complete: bool,
    paused_by_spec: bool,
    failure: RolloutFailure | None,
    rolled_back: RolledBack | None,
    canary: CanaryStatus | None,
    canaries_done: bool,
    mode: str,
    offline: Sequence[str],
    locked: Sequence[str],
    pre_pull: PrePullStatus | None = None,
) -> str:
    progress = f"{counts.healthy} of {counts.total} robots healthy on revision {target}"
    if failure is not None:
        return (
            f"{failure.message} Paused; fix the robots and `coral rollout resume`, or `coral rollout undo`."
        )
    parts = [progress]
    if rolled_back is not None:
        parts.append(f"rolled back from revision {rolled_back.from_revision} ({rolled_back.reason})")
    if paused_by_spec:
        parts.append("paused (spec.rollout.paused)")
    if canary is not None and not canaries_done:
        if canary.healthy_since:
            parts.append(f"canaries healthy since {canary.healthy_since}, holding")
        else:
            parts.append(f"canaries {canary.healthy} of {canary.robots} healthy")
    if pre_pull is not None and pre_pull.robots:
        parts.append(describe_pre_pull(pre_pull))
    if locked:
        parts.append(f"{len(locked)} waiting for running trees ({shown(locked[:MAX_NAMED], len(locked))})")
    if offline:
        verb = {"Skip": "skipped", "Wait": "waited for", "CountUnavailable": "counted unavailable"}[mode]
        parts.append(f"{len(offline)} offline robots {verb} ({shown(offline[:MAX_NAMED], len(offline))})")
    if complete:
        parts.append("complete")
    return "; ".join(parts) + "."


def describe_pre_pull(pre_pull: PrePullStatus) -> str:
    """The pre-pull's progress as a clause: how many robots have the images, and who failed."""
    text = f"images on {pre_pull.pulled} of {pre_pull.robots} robots to move"
    if pre_pull.pulling:
        text += f", {pre_pull.pulling} pulling"
    if pre_pull.failed:
        failed = [f.robot for f in pre_pull.failures]
        text += f", {pre_pull.failed} failed ({shown(failed, pre_pull.failed)})"
    if not pre_pull.released:
        text += ", no robot moves before they are pulled"
    return text


def _quarter(done: int, total: int) -> int:
    return 4 * done // total if total else 0


def build_events(
    previous: RolloutStatus | None,
    status: RolloutStatus,
    moves: dict[str, str],
    locked: Sequence[str],
    offline: Sequence[str],
    mode: str,
) -> list[RolloutEvent]:
    events = []
    same = previous is not None and previous.revision == status.revision
    if not same and moves:
        events.append(
            RolloutEvent(
                "RolloutStarted",
                f"Rolling out revision {status.revision} over {status.counts.total} robots, "
                f"at most {status.counts.max_unavailable} unavailable at a time.",
            )
        )
    quarter = _quarter(status.counts.updated, status.counts.total)
    if moves and (
        not same or previous is None or quarter > _quarter(previous.counts.updated, previous.counts.total)
    ):
        # One Event per quarter of the fleet, not per pass: a fleet rollout makes hundreds of passes.
        names = sorted(moves)
        events.append(
            RolloutEvent(
                "RobotsUpdating",
                f"{status.counts.updated} of {status.counts.total} robots on revision {status.revision}; "
                f"moving {len(names)} more: {shown(names[:MAX_NAMED], len(names))}.",
            )
        )
    was_paused = bool(same and previous and previous.paused)
    if status.paused and not was_paused and status.failure is None:
        events.append(RolloutEvent("RolloutPaused", f"Rollout of revision {status.revision} paused."))
    if was_paused and not status.paused:
        events.append(RolloutEvent("RolloutResumed", f"Rollout of revision {status.revision} resumed."))
    if locked and not (same and previous and previous.counts.locked):
        events.append(
            RolloutEvent(
                "WaitingForRunningTrees",
                f"{len(locked)} robots keep their revision until their tree finishes: "
                f"{shown(locked[:MAX_NAMED], len(locked))}.",
            )
        )
    if offline and mode == "Wait" and not (same and previous and previous.counts.offline):
        events.append(
            RolloutEvent(
                "WaitingForOfflineRobots",
                "No robot moves until these offline robots are back: "
                f"{shown(offline[:MAX_NAMED], len(offline))}.",
                True,
            )
        )
    failed = status.pre_pull.failed if status.pre_pull is not None else 0
    failed_before = previous.pre_pull.failed if same and previous and previous.pre_pull else 0
    if status.pre_pull is not None and failed > failed_before:
        # One Event each time more robots fail, with the kubelet's words; these robots do not move.
        events.append(
            RolloutEvent(
                "ImagePrePullFailed",
                f"{failed} robots cannot pull the images of revision {status.revision}: "
                + "; ".join(f"{f.robot}: {f.message}" for f in status.pre_pull.failures[:3]),
                True,
            )
        )
    if status.complete and not (same and previous and previous.complete) and (previous is not None):
        events.append(
            RolloutEvent(
                "RolloutComplete",
                f"{status.counts.healthy} robots run revision {status.revision}"
                + (f"; {status.counts.offline} offline robots skipped." if status.counts.offline else "."),
            )
        )
    return events
