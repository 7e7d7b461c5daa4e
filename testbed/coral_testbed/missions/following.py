"""Follows the CoralInstances of a mission live: one line per robot whenever its tree moves.

Pure formatting (`describe`, `finished`) plus `follow`, the polling loop that `coral demo` prints
and the mission tests use to wait (bounded) for every robot's tree to end.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

DONE = ("SUCCESS", "FAILURE")


def tree(instance: dict[str, Any]) -> dict[str, Any]:
    return (instance.get("status") or {}).get("tree") or {}


def condition(instance: dict[str, Any], kind: str) -> dict[str, Any]:
    conditions = (instance.get("status") or {}).get("conditions") or []
    return next((c for c in conditions if c.get("type") == kind), {})


def robot(instance: dict[str, Any]) -> str:
    return str((instance.get("spec") or {}).get("robot", instance["metadata"]["name"]))


def describe(instance: dict[str, Any], width: int = 70) -> str:
    """`robot-1  RUNNING  ticks 120  Main/.../ProcessScan` plus what is wrong, if anything."""
    status = tree(instance)
    root = status.get("rootStatus") or ("IDLE" if status else "-")
    path = str(status.get("activePath") or "")
    if len(path) > width:
        path = "..." + path[-(width - 3) :]
    parts = [f"{robot(instance):<16}", f"{root:<8}", f"ticks {status.get('tickCount', 0):<5}", path]
    ready = condition(instance, "Ready")
    if ready and ready.get("status") != "True":
        parts.append(f"[{ready.get('reason')}]")
    degraded = condition(instance, "LibraryDegraded")
    if degraded.get("status") == "True":
        parts.append(f"[LibraryDegraded: {degraded.get('message')}]")
    if status.get("message"):
        parts.append(f"({status['message']})")
    return "  ".join(p for p in parts if p).rstrip()


def finished(instances: list[dict[str, Any]], robots: list[str]) -> bool:
    """True when every one of `robots` has an instance whose tree ended (SUCCESS or FAILURE)."""
    ended = {robot(i) for i in instances if tree(i).get("rootStatus") in DONE}
    return set(robots) <= ended


def follow(
    list_instances: Callable[[], list[dict[str, Any]]],
    until: Callable[[list[dict[str, Any]]], bool],
    timeout: float,
    echo: Callable[[str], None] | None = None,
    check: Callable[[], None] = lambda: None,
    interval: float = 0.5,
) -> list[dict[str, Any]]:
    """Polls the instances until `until(instances)`; echoes a robot's line when it changes.

    Raises:
        TimeoutError: `until` did not hold within `timeout` seconds (the message has every line).
    """
    deadline = time.monotonic() + timeout
    shown: dict[str, str] = {}
    while True:
        check()
        instances = list_instances()
        for instance in sorted(instances, key=robot):
            # Tick counts change on every report; show a robot again only when something else did.
            line = describe(instance)
            key = line.replace(f"ticks {tree(instance).get('tickCount', 0):<5}", "")
            if echo is not None and shown.get(robot(instance)) != key:
                echo(f"    {line}")
            shown[robot(instance)] = key
        if until(instances):
            return instances
        if time.monotonic() >= deadline:
            lines = "\n".join(describe(i) for i in instances) or "(no CoralInstance)"
            raise TimeoutError(f"mission not finished after {timeout:.0f} s:\n{lines}")
        time.sleep(interval)  # polling period of the API, not synchronisation
