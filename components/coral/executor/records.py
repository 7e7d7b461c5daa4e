"""Status records the executor emits, and the conditions in them. Pure builders.

Every record is a flat JSON-able dict with `ts` (Unix seconds) and `event`; sinks
(`coral.executor.sinks`) write them out. The record format is documented in docs/skillsets.md
("Status records") and read by the local runtime and the operator's Kubernetes sink.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

Record = dict[str, Any]

# Condition types (metav1.Condition-shaped; the Kubernetes sink adds observedGeneration).
PLUGINS_READY = "PluginsReady"
LIBRARY_DEGRADED = "LibraryDegraded"


@dataclass(frozen=True)
class Condition:
    type: str
    status: str  # "True" | "False"
    reason: str
    message: str
    last_transition_time: float

    def as_dict(self) -> Record:
        return {
            "type": self.type,
            "status": self.status,
            "reason": self.reason,
            "message": self.message,
            "lastTransitionTime": self.last_transition_time,
        }


def evolve_condition(
    previous: Condition | None, *, type: str, status: bool, reason: str, message: str, now: float
) -> Condition:
    """The new condition, keeping `last_transition_time` unless the status flipped."""
    text = "True" if status else "False"
    since = previous.last_transition_time if previous is not None and previous.status == text else now
    return Condition(type, text, reason, message, since)


def plugins_ready_condition(previous: Condition | None, missing: list[str], now: float) -> Condition:
    if missing:
        return evolve_condition(
            previous,
            type=PLUGINS_READY,
            status=False,
            reason="NodeTypesMissing",
            message="Waiting for node types no running component exports: " + ", ".join(missing),
            now=now,
        )
    return evolve_condition(
        previous,
        type=PLUGINS_READY,
        status=True,
        reason="AllNodeTypesLoaded",
        message="Every node type the tree uses is loaded.",
        now=now,
    )


def library_degraded_condition(previous: Condition | None, degraded: dict[str, str], now: float) -> Condition:
    if degraded:
        parts = [f"{name} ({reason})" for name, reason in sorted(degraded.items())]
        return evolve_condition(
            previous,
            type=LIBRARY_DEGRADED,
            status=True,
            reason="ComponentUnavailable",
            message="Loaded behaviors lost their component: " + "; ".join(parts) + ".",
            now=now,
        )
    return evolve_condition(
        previous,
        type=LIBRARY_DEGRADED,
        status=False,
        reason="ComponentsAlive",
        message="Every component with loaded behaviors is alive.",
        now=now,
    )


def active_path(nodes: list[Any]) -> str:
    """The deepest RUNNING node's path in a snapshot ("" when nothing runs).

    Snapshots list nodes depth-first, and RUNNING nodes form one chain from the root (or
    several under a Parallel), so the last RUNNING node listed is a deepest one.
    """
    running = [node for node in nodes if status_name(node.status) == "RUNNING"]
    return running[-1].path if running else ""


def status_name(status: Any) -> str:
    """`Status.RUNNING` (or any enum) -> "RUNNING"."""
    return str(getattr(status, "name", status))
