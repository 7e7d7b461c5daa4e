"""The pods the operator builds for one robot of a small system, as the API server would serve them."""

from __future__ import annotations

import copy
from typing import Any

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import instances, pods
from coral_operator.planning.observed import RobotNode

TREE = '<root BTCPP_format="4"><BehaviorTree ID="Main"><AlwaysSuccess/></BehaviorTree></root>\n'
PARAMS = "driver:\n  ros__parameters:\n    rate: 10\n"
TREE_MAP = "sys-tree-1"
PARAMS_MAP = "sys-params-1"
CONFIG_MAPS = {TREE_MAP: {"tree.xml": TREE}, PARAMS_MAP: {"params.yaml": PARAMS}}
SPEC: dict[str, Any] = {
    "robots": {"matchLabels": {"fleet": "a"}},
    "parameters": {"inline": PARAMS},
    "tree": {"inline": TREE},
    "drivers": [{"name": "lidar", "image": "example/lidar:1"}],
    "skillsets": [{"name": "slam", "image": "example/slam:1"}],
    "executors": [{"name": "executor", "image": "example/executor:1"}],
}


def system(**changes: Any) -> dict[str, Any]:
    return copy.deepcopy(SPEC) | changes


def robot_pods(spec: dict[str, Any], robot: str = "r1") -> list[dict[str, Any]]:
    template = instances.build_template(CoralSystemSpec.model_validate(spec), TREE_MAP, PARAMS_MAP)
    node = RobotNode(
        node_name=robot,
        robot=robot,
        labels={"coral.dev/robot": robot},
        ready=True,
        last_seen=None,
        reachable=True,
    )
    instance_spec = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", node, template))
    built = pods.build_pods(spec=instance_spec, instance=f"sys-{robot}", namespace="ns", instance_uid="uid-1")
    for pod in built:
        pod["status"] = {"phase": "Running", "containerStatuses": [{"name": "c", "started": True}]}
    return built
