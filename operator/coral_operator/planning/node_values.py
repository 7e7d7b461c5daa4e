"""Values from a robot's own Node in an override: `${robot.name}`, `${robot.labels['KEY']}`,
`${robot.annotations['KEY']}`, and `$${` for a literal `${` (docs/overrides.md). Pure; used by
`planning.overrides` and `planning.effective`.
"""

from __future__ import annotations

import re
from typing import Any

from coral_operator.planning.observed import RobotNode

NODE_VALUE = re.compile(r"\$\$\{|\$\{([^}]*)\}")
_REFERENCE = re.compile(r"robot\.(?:(name)|(labels|annotations)\['([^'\]]+)'\])")


class Unresolved(Exception):
    """A value that cannot be resolved for a robot; `where` names the spec field."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(message)
        self.where = where
        self.message = message


def references(text: str) -> set[str]:
    """The Node references (`robot.name`, `robot.labels['k']`, ...) written in `text`."""
    return {m.group(1) for m in NODE_VALUE.finditer(text) if m.group(1) is not None}


def node_value(reference: str, robot: RobotNode) -> str | None:
    """The value a reference stands for on `robot`; None when the Node lacks the key.

    Raises:
        ValueError: not a reference this syntax knows.
    """
    parsed = _REFERENCE.fullmatch(reference.strip())
    if parsed is None:
        raise ValueError(
            f"unknown reference ${{{reference}}}; use ${{robot.name}}, ${{robot.labels['KEY']}} "
            "or ${robot.annotations['KEY']}"
        )
    if parsed.group(1):
        return robot.robot
    source = robot.labels if parsed.group(2) == "labels" else robot.annotations
    return source.get(parsed.group(3))


def substitute(text: str, robot: RobotNode, where: str) -> str:
    """`text` with the robot's Node values put in for its references."""

    def replace(match: re.Match[str]) -> str:
        if match.group(1) is None:
            return "${"
        try:
            value = node_value(match.group(1), robot)
        except ValueError as error:
            raise Unresolved(where, str(error)) from None
        if value is None:
            kind = "label" if "labels" in match.group(1) else "annotation"
            raise Unresolved(where, f"${{{match.group(1)}}}: the robot's Node has no {kind} of that key")
        return value

    return NODE_VALUE.sub(replace, text)


def substitute_values(value: Any, robot: RobotNode, where: str) -> Any:
    """`substitute` over every string of a parsed document; `where` grows with the path."""
    if isinstance(value, str):
        return substitute(value, robot, where)
    if isinstance(value, dict):
        return {k: substitute_values(v, robot, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, list):
        return [substitute_values(v, robot, f"{where}[{i}]") for i, v in enumerate(value)]
    return value
