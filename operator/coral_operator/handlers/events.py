"""Kubernetes Events for what a user watching `kubectl describe` should see: objects the operator
created or deleted and condition transitions. Called by the handlers.
"""

from __future__ import annotations

from typing import Any

import kopf

from coral_operator.api import keys

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
_DELIVERY_FAILURES = {"PodRefused", "ImagePullFailed", "PodUnschedulable"}


def info(body: kopf.Body, reason: str, message: str) -> None:
    # kopf.event, not kopf.info: the posting level (WARNING) keeps kopf's own chatter out, not ours.
    kopf.event(body, type="Normal", reason=reason, message=message)


def on_condition_changes(body: kopf.Body, old: list[dict[str, Any]], new: list[dict[str, Any]]) -> None:
    """Post one Event per notable condition whose status or message changed."""
    before = {c.get(keys.CONDITION.type): c for c in old}
    for condition in new:
        ctype, status = condition[keys.CONDITION.type], condition[keys.CONDITION.status]
        why, text = condition[keys.CONDITION.reason], condition[keys.CONDITION.message]
        previous = before.get(ctype)
        if ctype == "ComponentsReady" and why in _DELIVERY_FAILURES:
            if not previous or (
                previous.get(keys.CONDITION.reason),
                previous.get(keys.CONDITION.message),
            ) != (why, text):
                kopf.event(body, type="Warning", reason=why, message=text)
            continue
        key = (ctype, status)
        if key not in _NOTABLE:
            continue
        warning, reason = _NOTABLE[key]
        if previous is None and not warning and ctype != "Ready":
            # Good news is news only as a recovery: a robot reachable from the start says nothing.
            continue
        if (
            previous
            and previous.get(keys.CONDITION.status) == status
            and previous.get(keys.CONDITION.message) == text
        ):
            continue
        message = text or why
        kopf.event(body, type="Warning" if warning else "Normal", reason=reason, message=message)
