"""What a component image declares it exports, as one OCI label the operator reads from a registry.

The build writes the label from the same plugin manifest the component exports at runtime
(`coral.plugins.manifest`), so the behaviors, their ports and the versions the operator checks a
tree against before any pod exists are the ones the executor will load. The label holds compact
JSON; an image without it declares nothing, and callers fall back to finding out on the robot.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

EXPORTS_LABEL = "dev.coral.exports"
"""The image label holding the export declaration (JSON, see `ImageExports.to_label`)."""
LABEL_SCHEMA = 1
BTCPP_COMPATIBLE = "4"
"""The BT.CPP tree format the engine reads (`BTCPP_format="4"`)."""


class ExportsError(ValueError):
    """A label that is present but cannot be read; `str()` names the image and the field."""


@dataclass(frozen=True)
class DeclaredPort:
    name: str
    direction: str = "input"
    type: str = "any"
    default: str | None = None


@dataclass(frozen=True)
class DeclaredBehavior:
    id: str
    kind: str
    ports: tuple[DeclaredPort, ...] = ()


@dataclass(frozen=True)
class ImageExports:
    """One image's declaration: its component, the versions it was built for, its behaviors."""

    component: str
    kind: str
    coral_version: str
    ros_distro: str
    btcpp_version: str = BTCPP_COMPATIBLE
    behaviors: tuple[DeclaredBehavior, ...] = field(default_factory=tuple)

    def to_label(self) -> str:
        body = {
            "schema": LABEL_SCHEMA,
            "component": self.component,
            "kind": self.kind,
            "coral": self.coral_version,
            "ros": self.ros_distro,
            "btcpp": self.btcpp_version,
            "behaviors": [
                {
                    "id": b.id,
                    "kind": b.kind,
                    "ports": [
                        {"name": p.name, "direction": p.direction, "type": p.type, "default": p.default}
                        for p in b.ports
                    ],
                }
                for b in self.behaviors
            ],
        }
        return json.dumps(body, separators=(",", ":"), sort_keys=True)


def major_of(version: str) -> str:
    """Major component of a dotted version; for 0.x releases the minor counts too (semver rule)."""
    parts = version.split(".")
    if parts[0] == "0" and len(parts) > 1:
        return f"0.{parts[1]}"
    return parts[0]


def _text(raw: Mapping[str, Any], key: str, where: str) -> str:
    value = raw.get(key)
    if not isinstance(value, str) or not value:
        raise ExportsError(f"{where}: field {key!r} is missing or not a string")
    return value


def _behavior(raw: Any, where: str) -> DeclaredBehavior:
    if not isinstance(raw, dict):
        raise ExportsError(f"{where}: a behavior is not an object")
    ports = raw.get("ports") or []
    if not isinstance(ports, list) or not all(
        isinstance(p, dict) and isinstance(p.get("name"), str) for p in ports
    ):
        raise ExportsError(f"{where}: behavior {raw.get('id')!r}: ports must be objects with a name")
    return DeclaredBehavior(
        id=_text(raw, "id", where),
        kind=_text(raw, "kind", where),
        ports=tuple(
            DeclaredPort(
                name=p["name"],
                direction=str(p.get("direction") or "input"),
                type=str(p.get("type") or "any"),
                default=None if p.get("default") is None else str(p["default"]),
            )
            for p in ports
        ),
    )


def from_labels(labels: Mapping[str, str], image: str) -> ImageExports | None:
    """The declaration in an image's labels, None when the image declares nothing."""
    text = labels.get(EXPORTS_LABEL)
    if text is None:
        return None
    where = f"image {image}: label {EXPORTS_LABEL}"
    try:
        raw = json.loads(text)
    except ValueError as err:
        raise ExportsError(f"{where}: not JSON ({err})") from err
    if not isinstance(raw, dict):
        raise ExportsError(f"{where}: not a JSON object")
    if raw.get("schema") != LABEL_SCHEMA:
        raise ExportsError(f"{where}: schema {raw.get('schema')!r} is not {LABEL_SCHEMA}")
    behaviors = raw.get("behaviors") or []
    if not isinstance(behaviors, list):
        raise ExportsError(f"{where}: field 'behaviors' is not a list")
    return ImageExports(
        component=_text(raw, "component", where),
        kind=_text(raw, "kind", where),
        coral_version=_text(raw, "coral", where),
        ros_distro=_text(raw, "ros", where),
        btcpp_version=str(raw.get("btcpp") or BTCPP_COMPATIBLE),
        behaviors=tuple(_behavior(b, where) for b in behaviors),
    )
