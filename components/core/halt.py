"""A halt request as a robot reads it from its CoralInstance's spec (`spec.halt`).

The operator copies a CoralSystem's `spec.halt` into the spec of every robot it selects; the
robot's executor follows its own instance and halts its tree while the field is set. It lives in
the contract (not the operator's API) because both sides read it.
"""

from __future__ import annotations

from coral_core.wire import CamelModel
from pydantic import Field

MAX_PARK_SECONDS = 3600


class HaltRequest(CamelModel):
    """Halt the tree (as BT.CPP's `haltTree()` does) and tick it no more until the halt is lifted."""

    park_tree: str | None = Field(default=None, min_length=1, max_length=253)
    """ID of a `<BehaviorTree>` of the system's tree document to tick to its end before halting,
    for example one that drives the robot to a safe spot; none halts at once."""
    park_timeout_seconds: int = Field(default=30, ge=1, le=MAX_PARK_SECONDS)
    """How long the park tree may run; it is halted when the time is up."""
