"""An executor's `metrics` field: off by default, the flag and the named container port when set,
one port per executor, and the pod of a robot (`PodPerRobot`) with port names unique. Pure."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import METRICS_PORTS_DIFFER, CoralSystemSpec
from coral_operator.planning import instances, pods
from operator_specs import BASE_SPEC, robot
from pydantic import ValidationError

SECOND = {"name": "second", "image": "example/executor:1"}


def _spec(*executors: dict[str, Any], **top: Any) -> dict[str, Any]:
    raw = copy.deepcopy(BASE_SPEC) | {"ros": {"network": "Pod"}}
    raw["executors"] = [{"name": "executor", "image": "example/executor:1"} | e for e in executors]
    raw.update(top)
    return raw


def _executors(raw: dict[str, Any]) -> dict[str, dict[str, Any]]:
    template = instances.build_template(CoralSystemSpec.model_validate(raw), "t", "p")
    spec = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    built = pods.build_pods(spec=spec, instance="sys-r1", namespace="ns", instance_uid="u")
    names = {e["name"] for e in raw["executors"]}
    return {c["name"]: c for pod in built for c in pod["spec"]["containers"] if c["name"] in names}


def test_an_executor_serves_no_metrics_unless_asked() -> None:
    container = _executors(_spec({}))["executor"]
    assert "ports" not in container
    assert not any("--metrics" in part for part in container.get("command", []) + container.get("args", []))


def test_an_executor_asked_for_metrics_gets_the_flag_and_a_port_named_metrics() -> None:
    container = _executors(_spec({"metrics": {"port": 9464}}))["executor"]
    assert container["command"][-2:] == ["--metrics-port", "9464"]
    assert container["ports"] == [{"name": "metrics", "containerPort": 9464, "protocol": "TCP"}]


def test_executors_sharing_a_robots_pod_get_port_names_of_their_own() -> None:
    raw = _spec({"metrics": {"port": 9464}}, SECOND | {"metrics": {"port": 9465}}, layout="PodPerRobot")
    containers = _executors(raw)
    assert [p["name"] for c in containers.values() for p in c["ports"]] == ["metrics-0", "metrics-1"]


@pytest.mark.parametrize(
    ("story", "executors", "match"),
    [
        (
            "two executors on one port",
            [{"metrics": {"port": 9464}}, SECOND | {"metrics": {"port": 9464}}],
            "must differ",
        ),
        ("a port below 1024 (components run as non-root)", [{"metrics": {"port": 80}}], "metrics"),
        ("no port", [{"metrics": {}}], "metrics"),
    ],
)
def test_bad_metrics_settings_are_refused(story: str, executors: list[dict[str, Any]], match: str) -> None:
    with pytest.raises(ValidationError, match=match):
        CoralSystemSpec.model_validate(_spec(*executors))
    assert "differ" in METRICS_PORTS_DIFFER
