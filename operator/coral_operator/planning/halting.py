"""From a CoralSystem's `spec.halt` to the halt request each robot's CoralInstance carries.

Pure; called by `planning.system_pass` for every robot it builds an instance for. The request is
one of the robot's own spec fields (`observed.ROBOT_SPEC_FIELDS`), outside the revision's template,
so halting or resuming changes neither the revision nor any pod: only the executor, which follows
its instance, acts on it.
"""

from __future__ import annotations

from typing import Any

from coral_core.halt import HaltRequest

from coral_operator.api.system import HaltSpec


def halt_of_robot(halt: HaltSpec | None, robot: str) -> dict[str, Any] | None:
    """The instance's `spec.halt` (wire format) for `robot`, or None while its tree should run."""
    if halt is None or (halt.robots and robot not in halt.robots):
        return None
    return HaltRequest(park_tree=halt.park_tree, park_timeout_seconds=halt.park_timeout_seconds).to_wire()
