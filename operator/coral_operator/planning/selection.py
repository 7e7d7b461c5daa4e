"""Which robot Nodes a CoralSystem's selector matches. Pure; called by the system handler."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from coral_operator.api.common import LabelSelector, LabelSelectorRequirement
from coral_operator.planning.observed import RobotNode


def _meets(labels: Mapping[str, str], requirement: LabelSelectorRequirement) -> bool:
    present = requirement.key in labels
    if requirement.operator == "Exists":
        return present
    if requirement.operator == "DoesNotExist":
        return not present
    if requirement.operator == "In":
        return present and labels[requirement.key] in requirement.values
    return not present or labels[requirement.key] not in requirement.values


def matches(selector: LabelSelector, labels: Mapping[str, str]) -> bool:
    """Kubernetes label-selector semantics; an empty selector matches nothing (refused by the CRD)."""
    if not selector.match_labels and not selector.match_expressions:
        return False
    if any(labels.get(key) != value for key, value in selector.match_labels.items()):
        return False
    return all(_meets(labels, requirement) for requirement in selector.match_expressions)


def select_robots(selector: LabelSelector, nodes: Iterable[RobotNode]) -> list[RobotNode]:
    """Robots matching the selector, sorted by robot name; a robot name claimed by two Nodes keeps
    the first Node by name, so the choice is stable."""
    chosen: dict[str, RobotNode] = {}
    for node in sorted(nodes, key=lambda n: n.node_name):
        if matches(selector, node.labels) and node.robot not in chosen:
            chosen[node.robot] = node
    return [chosen[name] for name in sorted(chosen)]
