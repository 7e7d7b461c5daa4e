"""When a CoralInstance status is written: at once when a verdict changes, later when it can wait.

A verdict (a condition's status, why it is Stalled, whether its robot is reachable, for which
generation) is written at once: the system's rollout and every client read it. Progress alone (a
stage's message, a pod's phase) waits to ride along with the next verdict, and so does a status
that would tell no reader more than the one written already (`stale_status_says_as_much`,
`pending_status_says_as_much`). A write that can wait goes out `progress_interval` after its
anchor: the last status write for progress, the first sight of the generation otherwise. Pure;
`reconcile.instances` keeps the anchors and counts (`reconcile.pacing`).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from typing import Any

from coral_operator.api import keys
from coral_operator.status import transitions
from coral_operator.status.conditions import ConditionType as C
from coral_operator.status.transitions import find

# Status changes that change no verdict (a stage's message, a pod's phase) wait this long before
# they are written. A new instance reads as pending meanwhile (the CRD's default status), so a
# robot that starts within it costs one status write, when it is Ready.
PROGRESS_INTERVAL_S = 10.0
# Each further progress write before the next verdict waits twice as long as the one before, up
# to this: a start of a minute and a half (a loaded control plane, a slow image pull) is reported
# at 10, 30 and 70 s instead of every 10 s, and its robot's writes stay bounded however slow it is.
PROGRESS_INTERVAL_MAX_S = 60.0
# A fleet's robots start and update together, so their progress writes come together too: the
# intervals of a large system stretch so that its robots write progress at most this often between
# them. A CoralInstance status patch costs the API server 7 to 10 ms of CPU; at a thousand robots,
# 10 s apart, progress was more than half of a first deployment's status writes and slowed the
# very starts it reported (docs/architecture.md, "The operator: from spec to pods to status").
SYSTEM_PROGRESS_WRITES_PER_S = 20.0


class Anchor(enum.Enum):
    """What a write that can wait counts its interval from."""

    LAST_WRITE = "last write"
    """Progress only: the last status write."""
    GENERATION_SEEN = "generation seen"
    """A status that says no more than the one written: the first sight of the generation."""


def progress_interval(deferred_writes: int, robots: int = 1) -> float:
    """How long a status that can wait (`deferred_writes` such writes since the last verdict) waits
    after the last write, or after the spec change for the first, in a system of `robots`."""
    first = max(PROGRESS_INTERVAL_S, robots / SYSTEM_PROGRESS_WRITES_PER_S)
    return min(first * 2**deferred_writes, max(PROGRESS_INTERVAL_MAX_S, first))


def can_wait(current: Mapping[str, Any], new: Mapping[str, Any], generation: int | None) -> Anchor | None:
    """Whether writing `new` over `current` can wait, and from what; None: write it now."""
    if verdict_of(current) == verdict_of(new):
        return Anchor.LAST_WRITE
    if stale_status_says_as_much(current, new, generation) or pending_status_says_as_much(current, new):
        return Anchor.GENERATION_SEEN
    return None


def wait_left(*, since: float, now: float, deferred_writes: int, robots: int) -> float:
    """Seconds a write that can wait still waits (none when not positive); times are monotonic."""
    return progress_interval(deferred_writes, robots) - (now - since)


def verdict_of(status: Mapping[str, Any]) -> tuple[Any, ...]:
    """What of an instance's status is a verdict: the status of each condition, why it is Stalled,
    whether its robot is reachable, and for which generation.

    A change here is written at once (the system's rollout reads it); anything else (a stage's
    message, a pod's phase or restarts) waits to ride along with the next write.
    """
    conditions = _entries(status.get(keys.INSTANCE_STATUS.conditions))
    kind, state, why = keys.CONDITION.type, keys.CONDITION.status, keys.CONDITION.reason
    stalled = next((c for c in conditions if c.get(kind) == C.STALLED), {})
    robot = _mapping(status.get(keys.INSTANCE_STATUS.robot))
    return (
        status.get(keys.INSTANCE_STATUS.observed_generation),
        robot.get(keys.ROBOT.reachable),
        robot.get(keys.ROBOT.node_ready),
        tuple((c.get(kind), c.get(state)) for c in conditions),
        stalled.get(why) if stalled.get(state) == "True" else None,
    )


def stale_status_says_as_much(
    current: Mapping[str, Any], new: Mapping[str, Any], generation: int | None
) -> bool:
    """Whether writing `new` would tell no reader more than `current` already does.

    `current` was written for an older generation, which kstatus, Argo CD's health check and the
    system's rollout (`kube.observing.observed_instance`) all read as "in progress"; `new` says
    only that this generation is progressing (Ready and Stalled both False) and leaves the robot's
    reachability as it was. Such a write can wait like progress, so an update costs one status
    write, when the robot is Ready or Stalled at its new revision, instead of two.
    """
    written = transitions.written_generation(current)
    if written is None or generation is None or written >= generation:
        return False
    before = _mapping(current.get(keys.INSTANCE_STATUS.robot))
    after = _mapping(new.get(keys.INSTANCE_STATUS.robot))
    return _only_progressing(new) and all(
        before.get(key) == after.get(key) for key in (keys.ROBOT.reachable, keys.ROBOT.node_ready)
    )


def pending_status_says_as_much(current: Mapping[str, Any], new: Mapping[str, Any]) -> bool:
    """Whether `current` is still the CRD's default for a new instance (`api.common.pending_status`:
    Reconciling=True, no `observedGeneration`), which every client reads as in progress, and
    `new` says only that the robot is starting: Ready and Stalled False, the robot reachable and
    its Node Ready. Such a write can wait like progress, so a robot that starts within
    `PROGRESS_INTERVAL_S` costs one status write, when it is Ready or Stalled, instead of two.
    A status-less instance (a CRD from before the default) is not covered: kstatus reads it as
    Current.
    """
    if current.get(keys.INSTANCE_STATUS.observed_generation) is not None:
        return False
    reconciling = find(_entries(current.get(keys.INSTANCE_STATUS.conditions)), C.RECONCILING) or {}
    if reconciling.get(keys.CONDITION.status) != "True":
        return False
    robot = new.get(keys.INSTANCE_STATUS.robot) or {}
    return _only_progressing(new) and all(
        robot.get(key) is True for key in (keys.ROBOT.reachable, keys.ROBOT.node_ready)
    )


def _only_progressing(status: Mapping[str, Any]) -> bool:
    conditions = _entries(status.get(keys.INSTANCE_STATUS.conditions))
    return all(
        (find(conditions, ctype) or {}).get(keys.CONDITION.status) == "False"
        for ctype in (C.READY, C.STALLED)
    )


# `current` may hold what an executor wrote over the operator's fields: read, never trusted.
def _entries(value: Any) -> list[dict[str, Any]]:
    return [entry for entry in value if isinstance(entry, dict)] if isinstance(value, list) else []


def _mapping(value: Any) -> Mapping[str, Any]:
    return value if isinstance(value, Mapping) else {}
