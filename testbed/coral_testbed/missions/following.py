"""Follows the CoralInstances of a mission live: a table redrawn in place on a terminal, else one
plain line per robot whenever its tree moves.

Pure formatting (`describe`, `table`, `finished`) plus `follow`, the polling loop that `coral demo`
shows and the mission tests use to wait (bounded) for every robot's tree to end.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from typing import Any

from coral_core import keys, terminal
from rich.table import Table
from rich.text import Text

DONE = ("SUCCESS", "FAILURE")


def tree(instance: dict[str, Any]) -> dict[str, Any]:
    """The executor's tree status as written (the wire names of `coral_core.instance_status.TreeState`)."""
    return (instance.get("status") or {}).get(keys.INSTANCE_STATUS.tree) or {}


def condition(instance: dict[str, Any], kind: str) -> dict[str, Any]:
    conditions = (instance.get("status") or {}).get("conditions") or []
    return next((c for c in conditions if c.get("type") == kind), {})


def robot(instance: dict[str, Any]) -> str:
    return str((instance.get("spec") or {}).get("robot", instance["metadata"]["name"]))


def describe(instance: dict[str, Any], width: int = 70) -> str:
    """`robot-1  RUNNING  ticks 120  Main/.../ProcessScan` plus what is wrong, if anything."""
    status = tree(instance)
    root = status.get(keys.TREE.root_status) or ("IDLE" if status else "-")
    path = str(status.get(keys.TREE.active_path) or "")
    if len(path) > width:
        path = "..." + path[-(width - 3) :]
    ticks = status.get(keys.TREE.tick_count, 0)
    parts = [f"{robot(instance):<16}", f"{root:<8}", f"ticks {ticks:<5}", path]
    return "  ".join(p for p in [*parts, *problems(instance)] if p).rstrip()


def problems(instance: dict[str, Any]) -> list[str]:
    """What is wrong with the robot's instance, as `[Reason]` / `(message)` notes."""
    notes = []
    ready = condition(instance, "Ready")
    if ready and ready.get("status") != "True":
        notes.append(f"[{ready.get('reason')}]")
    degraded = condition(instance, "LibraryDegraded")
    if degraded.get("status") == "True":
        notes.append(f"[LibraryDegraded: {degraded.get('message')}]")
    message = tree(instance).get(keys.TREE.message)
    if message:
        notes.append(f"({message})")
    return notes


def table(instances: list[dict[str, Any]]) -> Table:
    """One row a robot: root status (coloured), ticks, active node path, what is wrong."""
    rows = []
    for instance in sorted(instances, key=robot):
        status = tree(instance)
        root = status.get(keys.TREE.root_status) or ("IDLE" if status else "-")
        rows.append(
            [
                robot(instance),
                terminal.status_text(str(root)),
                str(status.get(keys.TREE.tick_count, 0)),
                str(status.get(keys.TREE.active_path) or ""),
                Text("  ".join(problems(instance)), style="red"),
            ]
        )
    return terminal.table(["ROBOT", "TREE", "TICKS", "ACTIVE NODE", "PROBLEMS"], rows, right=["TICKS"])


def _uids(path: str) -> list[int]:
    return [int(uid) for uid in re.findall(r"::(\d+)(?=/|$)", path)]


def tree_statuses(instance: dict[str, Any]) -> dict[int, str]:
    """uid -> status of the nodes the instance's status speaks of: the root (uid 1), the active
    chain while the tree runs, and the node of the last failure. Other nodes are not reported."""
    status = tree(instance)
    statuses: dict[int, str] = {}
    root = status.get(keys.TREE.root_status)
    if root:
        statuses[1] = str(root)
    if root == "RUNNING":
        statuses.update(dict.fromkeys(_uids(str(status.get(keys.TREE.active_path) or "")), "RUNNING"))
    failed = _uids(str((status.get(keys.TREE.last_failure) or {}).get(keys.TREE_FAILURE.path) or ""))
    if failed:
        statuses[failed[-1]] = "FAILURE"
    return statuses


def finished(instances: list[dict[str, Any]], robots: list[str]) -> bool:
    """True when every one of `robots` has an instance whose tree ended (SUCCESS or FAILURE)."""
    ended = {robot(i) for i in instances if tree(i).get(keys.TREE.root_status) in DONE}
    return set(robots) <= ended


def follow(
    list_instances: Callable[[], list[dict[str, Any]]],
    until: Callable[[list[dict[str, Any]]], bool],
    timeout: float,
    echo: Callable[[str], None] | None = None,
    check: Callable[[], None] = lambda: None,
    interval: float = 0.5,
    show: Callable[[list[dict[str, Any]]], None] | None = None,
) -> list[dict[str, Any]]:
    """Polls the instances until `until(instances)`; echoes a robot's line when it changes, and
    hands every poll's instances to `show` (a live display), if given.

    Raises:
        TimeoutError: `until` did not hold within `timeout` seconds (the message has every line).
    """
    deadline = time.monotonic() + timeout
    shown: dict[str, str] = {}
    # Not `wait_for`: each poll also echoes the robots whose line changed and feeds the live view,
    # and a timeout lists every robot's last line rather than one message.
    while True:
        check()
        instances = list_instances()
        if show is not None:
            show(instances)
        for instance in sorted(instances, key=robot):
            # Tick counts change on every report; show a robot again only when something else did.
            line = describe(instance)
            key = line.replace(f"ticks {tree(instance).get(keys.TREE.tick_count, 0):<5}", "")
            if echo is not None and shown.get(robot(instance)) != key:
                echo(f"    {line}")
            shown[robot(instance)] = key
        if until(instances):
            return instances
        if time.monotonic() >= deadline:
            lines = "\n".join(describe(i) for i in instances) or "(no CoralInstance)"
            raise TimeoutError(f"mission not finished after {timeout:.0f} s:\n{lines}")
        time.sleep(interval)  # polling period of the API, not synchronisation
