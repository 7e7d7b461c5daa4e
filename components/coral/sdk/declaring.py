"""Declaring the behaviors a skillset provides, and turning the declarations into manifest entries.

Behavior classes are ordinary `coral_core.bt.leaves` subclasses with class-level `PORTS`; a skillset
lists them in `Skillset.BEHAVIORS`. `behavior(...)` optionally sets the node ID and description.
`describe_behavior` is called by `coral.sdk.exporting` when the component exports its plugin.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from typing import Any, TypeVar

from coral.plugins import manifest as manifests

T = TypeVar("T", bound=type)

_KIND_BY_BASE_NAME = {
    "SyncAction": "action",
    "StatefulAction": "action",
    "ConditionNode": "condition",
}


def behavior(node_id: str | None = None, *, description: str = "") -> Callable[[T], T]:
    """Class decorator: the node ID the tree uses (default: the class name) and a one-line description."""

    def mark(cls: T) -> T:
        cls.CORAL_NODE_ID = node_id or cls.__name__  # type: ignore[attr-defined]
        if description:
            cls.CORAL_DESCRIPTION = description  # type: ignore[attr-defined]
        return cls

    return mark


def _port(name: str, direction: str, type: str, default: Any, description: str) -> Any:
    from coral_core.bt import PortDirection, PortSpec

    return PortSpec(
        name=name,
        direction=PortDirection(direction),
        type=type,
        default=None if default is None else str(default),
        description=description,
    )


def input_port(name: str, type: str = "any", default: Any = None, description: str = "") -> Any:
    """A `coral_core.bt.PortSpec` the node reads, like BT.CPP's `InputPort<T>(name, default, description)`."""
    return _port(name, "input", type, default, description)


def output_port(name: str, type: str = "any", description: str = "") -> Any:
    """A `coral_core.bt.PortSpec` the node writes."""
    return _port(name, "output", type, None, description)


def inout_port(name: str, type: str = "any", default: Any = None, description: str = "") -> Any:
    """A `coral_core.bt.PortSpec` the node reads and writes."""
    return _port(name, "inout", type, default, description)


def node_id_of(cls: type) -> str:
    return str(getattr(cls, "CORAL_NODE_ID", cls.__name__))


def _text(value: Any) -> str:
    return str(value.value if isinstance(value, enum.Enum) else value)


def kind_of(cls: type) -> str:
    """The BT.CPP category of a behavior class: its `KIND`, else inferred from its leaf base class."""
    kind = getattr(cls, "KIND", None)
    if kind is not None:
        return _text(kind).lower()
    for base in cls.__mro__:
        if base.__name__ in _KIND_BY_BASE_NAME:
            return _KIND_BY_BASE_NAME[base.__name__]
    raise TypeError(f"behavior class {cls.__qualname__} has no KIND and no coral_core.bt.leaves base class")


# BT.CPP reads these attributes itself (instance name, node type), so no port may use them.
RESERVED_PORT_NAMES = {"name", "ID"}


def port_entries(cls: type) -> list[manifests.PortEntry]:
    entries: list[manifests.PortEntry] = []
    for spec in getattr(cls, "PORTS", None) or []:
        if spec.name in RESERVED_PORT_NAMES or spec.name.startswith("_"):
            raise ValueError(f"behavior {cls.__qualname__}: port name {spec.name!r} is reserved by BT.CPP")
        default = getattr(spec, "default", None)
        entries.append(
            manifests.PortEntry(
                name=spec.name,
                direction=_text(getattr(spec, "direction", "input")).lower(),  # type: ignore[arg-type]
                type=_text(getattr(spec, "type", "any")),
                default=None if default is None else str(default),
                description=str(getattr(spec, "description", "") or ""),
            )
        )
    return entries


def describe_behavior(cls: type, module: str) -> manifests.BehaviorEntry:
    """The manifest entry for one behavior class, exported as `module` inside `behaviors/`."""
    doc = (cls.__doc__ or "").strip().splitlines()
    description = getattr(cls, "CORAL_DESCRIPTION", None) or (doc[0] if doc else "")
    return manifests.BehaviorEntry.model_validate(
        {
            "id": node_id_of(cls),
            "kind": kind_of(cls),
            "module": module,
            "class": cls.__name__,
            "ports": [entry.model_dump() for entry in port_entries(cls)],
            "description": description,
        }
    )
