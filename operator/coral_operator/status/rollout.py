"""The `RolloutComplete` condition of a CoralSystem, from its `status.rollout`.

One domain condition next to Ready/Reconciling/Stalled, so `kubectl wait
--for=condition=RolloutComplete`, Argo CD and Flux see where a rollout stands; its reason says why
it is not complete. Pure; called by the system handler after `planning.rollout` decided the pass.
"""

from __future__ import annotations

from enum import StrEnum

from coral_operator.api.rollout import RolloutStatus
from coral_operator.status.transitions import Verdict


class RolloutConditionType(StrEnum):
    """The rollout's condition type."""

    ROLLOUT_COMPLETE = "RolloutComplete"
    """Every robot taking part runs the target revision and passes the health gate."""


class RolloutReason(StrEnum):
    """Reasons of the `RolloutComplete` condition."""

    COMPLETE = "Complete"
    """Every robot taking part runs the target revision and passes the health gate."""
    IN_PROGRESS = "InProgress"
    """Robots are being moved in waves."""
    CANARY_HOLD = "CanaryHold"
    """The canaries are updated and must stay healthy for the hold time."""
    PAUSED = "Paused"
    """`spec.rollout.paused` is set."""
    HEALTH_GATE_FAILED = "HealthGateFailed"
    """Robots on the new revision failed the health gate; the rollout is paused."""
    ROLLED_BACK = "RolledBack"
    """The fleet returns to the previous revision (undo, or a failed health gate)."""
    WAITING_FOR_RUNNING_TREES = "WaitingForRunningTrees"
    """Only robots whose tree is RUNNING a mission are left (the update lock)."""
    WAITING_FOR_OFFLINE_ROBOTS = "WaitingForOfflineRobots"
    """Offline robots hold the rollout back (`offlineRobots: Wait` or `CountUnavailable`)."""


def evaluate_rollout(status: RolloutStatus) -> Verdict:
    """The `RolloutComplete` verdict; the first matching reason, in order of what a human must do."""
    kind = RolloutConditionType.ROLLOUT_COMPLETE
    if status.failure is not None:
        return Verdict(kind, False, RolloutReason.HEALTH_GATE_FAILED, status.message)
    if status.complete:
        reason = RolloutReason.COMPLETE if status.rolled_back is None else RolloutReason.ROLLED_BACK
        return Verdict(kind, True, reason, status.message)
    if status.rolled_back is not None:
        return Verdict(kind, False, RolloutReason.ROLLED_BACK, status.message)
    if status.paused:
        return Verdict(kind, False, RolloutReason.PAUSED, status.message)
    if status.canary is not None and not status.canary.promoted and status.canary.healthy_since:
        return Verdict(kind, False, RolloutReason.CANARY_HOLD, status.message)
    counts = status.counts
    left = counts.total - counts.updated
    if left and left == counts.locked:
        return Verdict(kind, False, RolloutReason.WAITING_FOR_RUNNING_TREES, status.message)
    if left and left == counts.offline:
        return Verdict(kind, False, RolloutReason.WAITING_FOR_OFFLINE_ROBOTS, status.message)
    return Verdict(kind, False, RolloutReason.IN_PROGRESS, status.message)
