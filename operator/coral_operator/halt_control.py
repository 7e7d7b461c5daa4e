"""What `coral halt` and `coral resume` do to a CoralSystem, as a small library.

Both write `spec.halt` (the field GitOps can set as well) with a merge patch that carries the
system's resourceVersion, so two people halting different robots at once do not lose one halt.
`halted` and `resumed` compute the new field (pure); `acknowledged` reads from a CoralInstance
whether its executor carried out what its spec asks.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coral_core import names
from kubernetes.client.exceptions import ApiException
from pydantic import ValidationError

from coral_operator.api.system import HaltSpec
from coral_operator.planning import naming
from coral_operator.status import executor_report
from coral_operator.system_control import SystemControl

# Writes that raced another writer of the system are tried again this many times.
_ATTEMPTS = 5


class HaltError(Exception):
    """The halt cannot be changed that way; the message says why."""


def halted(
    current: HaltSpec | None, robot: str | None, park_tree: str | None, park_timeout_s: int
) -> HaltSpec:
    """`spec.halt` once `robot` (None: every robot) is halted too."""
    if robot is None or (current is not None and not current.robots):
        robots: list[str] = []
    else:
        robots = sorted({*(current.robots if current else []), robot})
    return HaltSpec(robots=robots, park_tree=park_tree, park_timeout_seconds=park_timeout_s)


def resumed(current: HaltSpec | None, robot: str | None, system: str) -> HaltSpec | None:
    """`spec.halt` once `robot` (None: every robot) runs again; None when no robot stays halted.

    Raises:
        HaltError: one robot is to run again while the halt covers the whole fleet.
    """
    if current is None or robot is None:
        return None
    if not current.robots:
        raise HaltError(
            f"every robot of coralsystem/{system} is halted; resume them all, or halt the others by name"
        )
    robots = [r for r in current.robots if r != robot]
    return current.model_copy(update={"robots": robots}) if robots else None


def acknowledged(instance: Mapping[str, Any]) -> bool:
    """The instance's executor did what its `spec.halt` asks: halted while set, ticking while unset."""
    spec = instance.get("spec") or {}
    tree = executor_report.read_executor_report(instance.get("status") or {}).tree
    return (spec.get("halt") is not None) == (tree is not None and tree.halted is not None)


def wanted_on(instance: Mapping[str, Any], halt: HaltSpec | None) -> bool:
    """The operator has passed `halt` on to the instance: it asks its robot for the same."""
    robot = (instance.get("spec") or {}).get("robot", "")
    should_halt = halt is not None and (not halt.robots or robot in halt.robots)
    return ((instance.get("spec") or {}).get("halt") is not None) == should_halt


class HaltControl(SystemControl):
    """Halts and resumes the CoralSystems of one namespace."""

    error = HaltError

    def change(self, system: str, how: Any) -> HaltSpec | None:
        """Sets `spec.halt` to `how(current)`, again on a conflict with another writer; returns it."""
        for _ in range(_ATTEMPTS):
            body = self.read(system)
            new = how(_halt_of(body, system))
            patch = {
                "metadata": {"resourceVersion": body["metadata"]["resourceVersion"]},
                # Null removes the field (merge patch); the whole object replaces the old one's lists.
                "spec": {"halt": None if new is None else new.to_wire()},
            }
            try:
                self.patch(system, patch)
                return new
            except ApiException as error:
                if error.status != 409:
                    raise
        raise HaltError(f"coralsystem/{system} kept changing; try again")

    def instances(self, system: str, robot: str | None) -> list[dict[str, Any]]:
        """The system's CoralInstances, or the one of `robot`."""
        selector = f"{names.LABEL_SYSTEM}={naming.label_value(system)}"
        if robot is not None:
            selector += f",{names.LABEL_ROBOT}={naming.label_value(robot)}"
        listing = self.custom.list_namespaced_custom_object(
            names.GROUP, names.VERSION, self.namespace, names.INSTANCE_PLURAL, label_selector=selector
        )
        return list(listing.get("items") or [])


def _halt_of(body: Mapping[str, Any], system: str) -> HaltSpec | None:
    halt = (body.get("spec") or {}).get("halt")
    if halt is None:
        return None
    try:
        return HaltSpec.model_validate(halt)
    except ValidationError as error:
        raise HaltError(f"coralsystem/{system} spec.halt cannot be read: {error}") from error
