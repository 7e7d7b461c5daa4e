"""Pure builders of the Pod status the runner reports, shaped as a kubelet reports it.

Called by `runner.pods` after every supervision step; the result is compared with what was last
sent and patched only when it changed. Times are passed in, never read here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

RUNTIME = "coral-robot-runner"


def timestamp(moment: datetime) -> str:
    return moment.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def exit_code_of(returncode: int) -> int:
    """Popen's negative "killed by signal N" becomes the shell/kubelet convention 128+N."""
    return 128 - returncode if returncode < 0 else returncode


def terminated_state(
    code: int, started: datetime | None, finished: datetime, pid: int | None
) -> dict[str, Any]:
    state: dict[str, Any] = {
        "exitCode": code,
        "reason": "Completed" if code == 0 else "Error",
        "finishedAt": timestamp(finished),
    }
    if started is not None:
        state["startedAt"] = timestamp(started)
    if pid is not None:
        state["containerID"] = f"{RUNTIME}://{pid}"
    return state


def evaluate_phase(states: list[dict[str, Any]], prepared: bool) -> str:
    """Pod phase from container states ("running"/"waiting"/"terminated" dicts), as the kubelet decides.

    `Succeeded`/`Failed` only when every container terminated for good: the caller reports a
    container that will be restarted as waiting (CrashLoopBackOff), never as terminated.
    """
    if not prepared or not states:
        return "Pending"
    kinds = [next(iter(s)) for s in states]
    if any(k == "running" for k in kinds):
        return "Running"
    if all(k == "terminated" for k in kinds):
        failed = any(s["terminated"]["exitCode"] != 0 for s in states)
        return "Failed" if failed else "Succeeded"
    # Some waiting: either never started (Pending) or restarting after an exit (Running).
    return (
        "Running"
        if any(
            k != "waiting" or s["waiting"].get("reason") == "CrashLoopBackOff"
            for k, s in zip(kinds, states, strict=True)
        )
        else "Pending"
    )


@dataclass
class Conditions:
    """Pod conditions with kubelet transition semantics: the time changes only when the status flips."""

    seen: dict[str, tuple[str, str, str | None]] = field(default_factory=dict)

    def set(self, kind: str, status: bool, now: datetime, reason: str | None = None) -> None:
        value = "True" if status else "False"
        previous = self.seen.get(kind)
        when = previous[1] if previous and previous[0] == value else timestamp(now)
        self.seen[kind] = (value, when, reason)

    def to_wire(self) -> list[dict[str, Any]]:
        out = []
        for kind, (value, when, reason) in self.seen.items():
            item: dict[str, Any] = {"type": kind, "status": value, "lastTransitionTime": when}
            if reason:
                item["reason"] = reason
            out.append(item)
        return out


def build_status(
    *,
    phase: str,
    host_ip: str,
    start_time: datetime,
    conditions: Conditions,
    container_statuses: list[dict[str, Any]],
    message: str | None = None,
    reason: str | None = None,
) -> dict[str, Any]:
    status: dict[str, Any] = {
        "phase": phase,
        "hostIP": host_ip,
        "hostIPs": [{"ip": host_ip}],
        "podIP": host_ip,
        "podIPs": [{"ip": host_ip}],
        "startTime": timestamp(start_time),
        "conditions": conditions.to_wire(),
        "containerStatuses": container_statuses,
        "message": message,
        "reason": reason,
    }
    return status
