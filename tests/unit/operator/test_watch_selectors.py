"""The operator's pod and Node watches are filtered by the API server, so the selectors it sends
must select every pod it creates (in both layouts) and every robot Node, and nothing else."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_operator.api.common import LabelSelector
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.handlers import filters
from coral_operator.planning import instances, pods, selection
from operator_specs import robot


def _selects(selector: str, labels: dict[str, str]) -> bool:
    """The selector as sent (`key=value` and `key` terms), matched with the operator's own
    label-selector semantics (`planning.selection.matches`)."""
    equal = dict(term.split("=", 1) for term in selector.split(",") if "=" in term)
    exists = [{"key": term, "operator": "Exists"} for term in selector.split(",") if "=" not in term]
    parsed = LabelSelector.model_validate({"matchLabels": equal, "matchExpressions": exists})
    return selection.matches(parsed, labels)


def _selector(plural: str) -> str:
    return filters.watch_selectors()[("v1", plural)]


@pytest.mark.parametrize("layout", ["PodPerComponent", "PodPerRobot"])
def test_every_planned_pod_is_selected(layout: str, spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = CoralSystemSpec.model_validate(spec_dict(layout=layout))
    template = instances.build_template(spec, "tree-cm", "params-cm")
    instance_spec = CoralInstanceSpec.model_validate(
        instances.build_instance_spec("sys", robot("r1"), template)
    )
    planned = pods.build_pods(spec=instance_spec, instance="sys-r1", namespace="ns", instance_uid="u")
    assert planned
    for pod in planned:
        assert _selects(_selector("pods"), pod["metadata"]["labels"]), pod["metadata"]["name"]


def test_pods_of_other_applications_are_not_sent() -> None:
    selector = _selector("pods")
    assert not _selects(selector, {"app": "web"})
    # Another controller's pod that happens to carry an instance label.
    assert not _selects(selector, {"coral.dev/instance": "x", "app.kubernetes.io/managed-by": "helm"})


def test_robot_nodes_and_only_they_are_selected() -> None:
    assert _selects(_selector("nodes"), dict(robot("r1").labels))
    assert not _selects(_selector("nodes"), {"kubernetes.io/hostname": "control-plane"})
