"""The versioned plugin manifest: what a component exports and how an executor reads it back.

Written by `exporting.export_plugin` (skillset and driver side) and parsed by
`discovery.discover` (executor side). Parsing errors name the manifest file and the field.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

import pydantic
from coral_core import image_exports, parsing

SCHEMA_VERSION = 1
MANIFEST_NAME = "manifest.json"
READY_NAME = "ready"
BEHAVIORS_DIR = "behaviors"
INTERFACES_DIR = "interfaces"

# Component names double as ROS node names and folder names, so they follow the stricter of the two.
COMPONENT_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
NODE_ID_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

BehaviorKind = Literal["action", "condition", "control", "decorator"]
ComponentKind = Literal["skillset", "driver"]
PortDirectionName = Literal["input", "output", "inout"]


class ManifestError(ValueError):
    """A manifest that cannot be read: `str()` names the file and the field."""


class PortEntry(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", use_attribute_docstrings=True)

    name: str
    """Port name as written in the tree XML."""
    direction: PortDirectionName = "input"
    """Whether the node reads (`input`), writes (`output`) or both (`inout`)."""
    type: str = "any"
    """Type name the engine converts the port's string to (`int`, `double`, `bool`, `string`, ...)."""
    default: str | None = None
    """Value used when the tree leaves the port out; None means required."""
    description: str = ""
    """Shown in Groot2's palette."""


class BehaviorEntry(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", populate_by_name=True, use_attribute_docstrings=True)

    id: str
    """Node ID used in the tree XML."""
    kind: BehaviorKind
    """BT.CPP node category."""
    module: str
    """Module path relative to `behaviors/` (dotted), e.g. `example_behaviors`."""
    class_name: str = pydantic.Field(alias="class")
    """Class implementing the node inside `module`."""
    ports: list[PortEntry] = []
    """Declared ports."""
    description: str = ""
    """One line shown in tooling."""

    @pydantic.field_validator("id")
    @classmethod
    def _node_id_is_xml_name(cls, value: str) -> str:
        if not NODE_ID_RE.match(value):
            raise ValueError(f"node ID {value!r} is not a valid identifier")
        return value


class ComponentRef(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid")

    name: str
    kind: ComponentKind
    node_name: str
    namespace: str = "/"

    @pydantic.field_validator("name")
    @classmethod
    def _name_is_safe(cls, value: str) -> str:
        if not COMPONENT_NAME_RE.match(value):
            raise ValueError(f"component name {value!r} must match {COMPONENT_NAME_RE.pattern}")
        return value

    @property
    def node_fqn(self) -> str:
        namespace = self.namespace.rstrip("/")
        return f"{namespace}/{self.node_name}"


class PluginManifest(pydantic.BaseModel):
    """Everything an executor needs to decide whether and how to load a component's behaviors."""

    model_config = pydantic.ConfigDict(extra="forbid")

    schema_version: int
    component: ComponentRef
    coral_version: str
    ros_distro: str
    behaviors: list[BehaviorEntry] = []
    files: dict[str, str] = {}
    """Relative path -> sha256 hex digest of every exported file."""
    interface_packages: list[str] = []
    """Top-level import names found under `interfaces/`, put on the executor's import path."""
    exported_at: float = 0.0

    def content_hash(self) -> str:
        """A short digest over the exported files, stable across re-exports of the same content."""
        import hashlib

        digest = hashlib.sha256()
        for path in sorted(self.files):
            digest.update(f"{path}={self.files[path]}\n".encode())
        return digest.hexdigest()[:12]

    def to_json(self) -> str:
        return json.dumps(self.model_dump(by_alias=True), indent=2, sort_keys=True) + "\n"

    def image_exports(self) -> image_exports.ImageExports:
        """What an image of this component declares to the operator (its `dev.coral.exports` label)."""
        return image_exports.ImageExports(
            component=self.component.name,
            kind=self.component.kind,
            coral_version=self.coral_version,
            ros_distro=self.ros_distro,
            behaviors=tuple(
                image_exports.DeclaredBehavior(
                    id=b.id,
                    kind=b.kind,
                    ports=tuple(
                        image_exports.DeclaredPort(p.name, p.direction, p.type, p.default) for p in b.ports
                    ),
                )
                for b in self.behaviors
            ),
        )


def palette_behaviors(plugins: Iterable[PluginManifest]) -> list[BehaviorEntry]:
    """Every behavior the plugins export, by ID and then by component name: the order of a Groot2
    palette (`coral_core.bt.treenodesmodel`)."""
    owned = [(behavior, plugin.component.name) for plugin in plugins for behavior in plugin.behaviors]
    return [behavior for behavior, _owner in sorted(owned, key=lambda pair: (pair[0].id, pair[1]))]


def parse_manifest(text: str, source: str) -> PluginManifest:
    """Parse manifest JSON; `source` (a file name) prefixes every error."""
    try:
        raw = parsing.load_json(text)
    except json.JSONDecodeError as err:
        raise ManifestError(f"{source}:{err.lineno}: invalid JSON: {err.msg}") from err
    except ValueError as err:
        raise ManifestError(f"{source}: invalid JSON: {err}") from err
    if not isinstance(raw, dict):
        raise ManifestError(f"{source}: manifest must be a JSON object")
    version = raw.get("schema_version")
    if not isinstance(version, int):
        raise ManifestError(f"{source}: field 'schema_version' is missing or not an integer")
    try:
        return PluginManifest.model_validate(raw)
    except pydantic.ValidationError as err:
        first = err.errors()[0]
        field = ".".join(str(part) for part in first["loc"])
        raise ManifestError(f"{source}: field '{field}': {first['msg']}") from err


def read_manifest(plugin_dir: Path) -> PluginManifest:
    path = plugin_dir / MANIFEST_NAME
    try:
        text = parsing.read_text(path)
    except OSError as err:
        raise ManifestError(f"{path}: cannot read: {err.strerror}") from err
    except parsing.NotText as err:
        raise ManifestError(f"{path}:{err.line}: {err.reason}") from err
    return parse_manifest(text, str(path))
