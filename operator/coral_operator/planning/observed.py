"""Plain records of what the operator observed in the cluster, decoupled from API objects.

`kube.observing` builds them from API bodies; the planners and status builders read them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime


@dataclass(frozen=True)
class RobotNode:
    """A Node carrying the `coral.dev/robot` label."""

    node_name: str
    robot: str
    labels: dict[str, str]
    ready: bool
    last_seen: datetime | None = None


@dataclass(frozen=True)
class ObservedPod:
    """A component pod as last seen."""

    name: str
    component: str
    role: str
    revision: str
    pod_hash: str
    phase: str
    ready: bool
    created: datetime | None
    deleting: bool = False
    restarts: int = 0
    crash_looping: bool = False


@dataclass(frozen=True)
class ObservedInstance:
    """A CoralInstance as the system sees it."""

    name: str
    robot: str
    spec: dict
    revision: str
    ready: bool = False
    reachable: bool | None = None
    tree_root: str | None = None
    labels: dict[str, str] = field(default_factory=dict)
    stalled: bool = False
    """The instance is Stalled at its current generation (a component failed, or startup timed out)."""
