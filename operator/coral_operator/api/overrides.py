"""Per-robot overrides of a CoralSystem: what differs for the robots a selector picks (docs/overrides.md).

Resolved into each robot's effective configuration by `planning.overrides`; rendered into the CRD
by `api.crdgen` as part of `CoralSystemSpec.overrides`.
"""

from __future__ import annotations

import re
from typing import Annotated

from coral_core.wire import CamelModel
from pydantic import Field, field_validator

from coral_operator.api.common import LabelSelector
from coral_operator.api.components import DNS_LABEL, Component, EnvVar, ExecutorComponent

MAX_OVERRIDES = 32
MAX_OVERRIDE_FILE_BYTES = 32 * 1024
OVERRIDE_TREE_FILE_NAME = r"^[-_a-zA-Z0-9][-._a-zA-Z0-9]{0,62}$"
RESERVED_FILE_NAMES = ("tree.xml", "params.yaml")
OVERRIDE_NAMES_UNIQUE = "overrides must have unique names"
OVERRIDE_SELECTS = "overrides[].robots must select with at least one label or expression"


class ComponentsAdded(CamelModel):
    """Components the matched robots run besides the system's own."""

    drivers: list[Component] = Field(default_factory=list, max_length=8)
    """Drivers to add."""
    skillsets: list[Component] = Field(default_factory=list, max_length=8)
    """Skillsets to add."""
    executors: list[ExecutorComponent] = Field(default_factory=list, max_length=8)
    """Executors to add."""


class TreeOverride(CamelModel):
    """What differs in the tree: the main document, the tree to run, included files."""

    inline: str | None = Field(default=None, max_length=MAX_OVERRIDE_FILE_BYTES)
    """Replaces the system's main tree document (BT.CPP v4 XML)."""
    main_tree_id: str | None = Field(default=None, max_length=253)
    """Replaces `tree.mainTreeId`."""
    files: dict[str, Annotated[str, Field(max_length=MAX_OVERRIDE_FILE_BYTES)]] = Field(
        default_factory=dict, max_length=8
    )
    """Included files added, or replacing the system's file of the same name."""

    @field_validator("files")
    @classmethod
    def _file_names(cls, files: dict[str, str]) -> dict[str, str]:
        for name in files:
            if not re.fullmatch(OVERRIDE_TREE_FILE_NAME, name) or name in RESERVED_FILE_NAMES:
                raise ValueError(
                    f"{name!r}: tree file names are file names other than tree.xml and params.yaml"
                )
        return files


class Override(CamelModel):
    """What differs for the robots `robots` selects.

    Precedence: the system's spec, then every matching override, then the robot's Node values
    substituted into the override's values. Two matching overrides that set the same field to
    different values are a conflict, never settled by their order: the robot keeps what it runs
    and the system names both overrides. Values (parameters, env values, images) may use
    `${robot.name}`, `${robot.labels['KEY']}` and `${robot.annotations['KEY']}`; `$${` is a literal
    `${`."""

    name: str = Field(min_length=1, max_length=63, pattern=DNS_LABEL)
    """Name of the override, unique in the system; statuses and `coral config` use it."""
    robots: LabelSelector
    """Label selector over the system's robots (for example `coral.dev/model: spot`)."""
    parameters: str | None = Field(default=None, max_length=MAX_OVERRIDE_FILE_BYTES)
    """ROS parameters YAML deep-merged onto the system's: mappings merge key by key, any other
    value (a list too) replaces the system's."""
    env: list[EnvVar] = Field(default_factory=list, max_length=32)
    """Environment variables set in every component of the robot, replacing ones of the same name."""
    images: dict[
        Annotated[str, Field(max_length=40)], Annotated[str, Field(min_length=1, max_length=512)]
    ] = Field(default_factory=dict, max_length=32)
    """Component name -> the image it runs on these robots."""
    add: ComponentsAdded = Field(default_factory=ComponentsAdded)
    """Components these robots run besides the system's."""
    remove: list[Annotated[str, Field(max_length=40)]] = Field(default_factory=list, max_length=32)
    """Names of the system's components these robots do not run."""
    tree: TreeOverride | None = None
    """What differs in the tree."""


def check_overrides(overrides: list[Override]) -> str | None:
    """Why a list of overrides is refused as a whole (names, selectors), or None."""
    names = [o.name for o in overrides]
    if len(names) != len(set(names)):
        return OVERRIDE_NAMES_UNIQUE
    if any(not o.robots.match_labels and not o.robots.match_expressions for o in overrides):
        return OVERRIDE_SELECTS
    return None
