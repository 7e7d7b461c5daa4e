"""Bounds on what one CoralSystem expands to across its robots and on what one namespace's systems hold.

The schema bounds each string of a component (`api.components`) and the files a system carries
(`api.system`); what they add up to is checked here, because the schema cannot multiply by robots
or add up objects. Everything in a system's components (`ROBOT_FIELDS`) is copied into each
matched robot's CoralInstance and pods, and the operator keeps each robot's copy in memory while
the robot runs (docs/architecture.md, "The operator's memory"): a 0.7 MB system on 40 robots was
56 MB of objects (issue 47). Each refusal names the field and the figures. Called by
`planning.system_pass`; pure.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

ROBOT_FIELDS = ("ros", "drivers", "skillsets", "executors", "layout", "startup", "plugins")
"""The spec fields every robot's CoralInstance (and its pods) carries a copy of."""

MAX_ROBOT_SHARE_BYTES = 128 * 1024
"""What one robot's copy of the system may take (JSON bytes of `ROBOT_FIELDS`)."""
MAX_SYSTEM_EXPANSION_BYTES = 16 * 1024 * 1024
"""What one system may spread over its robots: the robot share times the matched robots."""
MAX_NAMESPACE_BYTES = 32 * 1024 * 1024
"""What the CoralSystems of one namespace may hold together: their specs plus their expansions."""


def json_bytes(value: Any) -> int:
    """The size of `value` as compact JSON, as the API server stores it."""
    return len(json.dumps(value, separators=(",", ":"), ensure_ascii=False).encode("utf-8", "surrogatepass"))


def robot_share_bytes(spec: Mapping[str, Any]) -> int:
    """What one robot's copy of the system takes (see `ROBOT_FIELDS`)."""
    return json_bytes({key: spec[key] for key in ROBOT_FIELDS if key in spec})


@dataclass(frozen=True)
class Footprint:
    """What one CoralSystem weighs, for the namespace's total."""

    name: str
    created: str
    """The creation timestamp: systems are counted oldest first, so a newcomer never pushes an
    older system over the namespace's bound."""
    spec_bytes: int
    share_bytes: int
    robots: int

    @property
    def total(self) -> int:
        return self.spec_bytes + self.share_bytes * self.robots


def check_expansion(share_bytes: int, robots: int) -> str | None:
    """Why the system's copies across `robots` are refused, or None."""
    fields = "spec.drivers, spec.skillsets and spec.executors (with spec.ros, startup and plugins)"
    if share_bytes > MAX_ROBOT_SHARE_BYTES:
        return (
            f"{fields}: {share_bytes:,} bytes are copied to every robot; the limit is "
            f"{MAX_ROBOT_SHARE_BYTES:,}"
        )
    expanded = share_bytes * robots
    if expanded > MAX_SYSTEM_EXPANSION_BYTES:
        return (
            f"{fields}: {share_bytes:,} bytes copied to each of {robots:,} matched robots make "
            f"{expanded:,} bytes; the limit is {MAX_SYSTEM_EXPANSION_BYTES:,}"
        )
    return None


def check_namespace(namespace: str, own: Footprint, others: Iterable[Footprint]) -> str | None:
    """Why the system is refused for what its namespace already holds, or None. Only systems
    created before it (then by name) count: the newest system is the one refused."""
    order = (own.created, own.name)
    earlier = [other for other in others if (other.created, other.name) < order and other.name != own.name]
    held = sum(other.total for other in earlier) + own.total
    if held <= MAX_NAMESPACE_BYTES:
        return None
    return (
        f"spec: the CoralSystems of namespace {namespace} would hold {held:,} bytes with this one "
        f"({len(earlier)} older systems and this one's {own.total:,}: spec plus its copies on "
        f"{own.robots} robots); the limit is {MAX_NAMESPACE_BYTES:,}"
    )
