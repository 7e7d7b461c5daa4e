"""Kubernetes Events for what a user watching `kubectl describe` should see.

Events are few and aggregated: a system pass posts one Event per kind of change with a count
(instances created, moved to a revision, retired, deleted; rollout waves), and condition changes of
the system. An instance posts only what concerns that robot alone and needs attention (warnings:
a refused pod, an unpullable image, an unreachable robot, a failed tree, and the recovery from a
pod or image failure it warned about); its progress is counted on its system.
The poster is injected (kopf's, from `handlers`), so this module needs no framework.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from coral_operator.api import keys

Poster = Callable[[dict[str, Any], str, str, str], None]
"""(object reference, `Normal` or `Warning`, reason, message) -> posts one Event."""

# Transitions worth an Event: (type, new status) -> (is a warning, reason).
_NOTABLE = {
    ("Ready", "True"): (False, "Ready"),
    ("Stalled", "True"): (True, "Stalled"),
    ("RobotReachable", "False"): (True, "RobotUnreachable"),
    ("RobotReachable", "True"): (False, "RobotReachable"),
    ("RobotsReachable", "False"): (True, "RobotsUnreachable"),
    ("TreeHealthy", "False"): (True, "TreeFailed"),
    ("LibraryDegraded", "True"): (True, "LibraryDegraded"),
}
# Reasons of `ComponentsReady=False` that no other Event tells the instance's user about (the pod's
# own Events name the pod, not the robot's instance, and a refused pod has none).
_DELIVERY_FAILURES = {"PodRefused", "ImagePullFailed", "ContainerRefused", "PodUnschedulable"}
RECOVERED = "Recovered"
"""The reason of the Normal Event an instance posts when one of `_DELIVERY_FAILURES` clears."""


def names(listed: list[str], shown: int = 10) -> str:
    """The first names, then how many more: a fleet has thousands."""
    text = ", ".join(listed[:shown])
    return text + (f" and {len(listed) - shown} more" if len(listed) > shown else "")


def condition_events(
    old: list[dict[str, Any]], new: list[dict[str, Any]], *, warnings_only: bool = False
) -> list[tuple[str, str, str]]:
    """(type, reason, message) of one Event per notable condition whose status or message changed."""
    before = {c.get(keys.CONDITION.type): c for c in old}
    found = []
    for condition in new:
        ctype, status = condition[keys.CONDITION.type], condition[keys.CONDITION.status]
        why, text = condition[keys.CONDITION.reason], condition[keys.CONDITION.message]
        previous = before.get(ctype)
        if ctype == "ComponentsReady":
            was = previous.get(keys.CONDITION.reason) if previous else None
            if why in _DELIVERY_FAILURES:
                if not previous or (was, previous.get(keys.CONDITION.message)) != (why, text):
                    found.append(("Warning", why, text))
            elif was in _DELIVERY_FAILURES:
                # The one piece of good news an instance tells: the end of a failure it warned
                # about, which the kubelet's back-off can bring minutes after the cause is gone.
                found.append(("Normal", RECOVERED, f"No longer {was}: {text}"))
            continue
        key = (ctype, status)
        if key not in _NOTABLE:
            continue
        warning, reason = _NOTABLE[key]
        if warnings_only and not warning:
            continue
        if previous is None and not warning and ctype != "Ready":
            # Good news is news only as a recovery: a robot reachable from the start says nothing.
            continue
        if (
            previous
            and previous.get(keys.CONDITION.status) == status
            and previous.get(keys.CONDITION.message) == text
        ):
            continue
        found.append(("Warning" if warning else "Normal", reason, text or why))
    return found
