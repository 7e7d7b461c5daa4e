"""Generated systems with overrides over generated fleets: every robot's effective configuration is valid,
or the system names that robot and the field at fault.

Property: a system pass never raises; each matched robot either gets an instance whose spec the
API accepts, whose ConfigMaps the pass writes and whose tree and parameters validate, or is listed
in the system's `InvalidRobotConfig` problem with an `spec.overrides` field; and reordering the
overrides changes nothing (they never outrank each other).
"""

from __future__ import annotations

import copy
from typing import Any

import yaml
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import system_pass, validation
from coral_operator.planning.observed import RobotNode
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from operator_specs import BASE_SPEC, TREE, plan_pass
from pydantic import ValidationError

MODELS = ["spot", "arm", "server"]
BROKEN_TREE = '<root BTCPP_format="4">\n<BehaviorTree ID="Main">\n<Sequence>'
VALUES = st.sampled_from(
    [
        "1",
        "x",
        "${robot.name}",
        "${robot.labels['coral.dev/model']}",
        "${robot.labels['site']}",
        "${robot.annotations['ip']}",
        "$${robot.name}",
        "${robot.nope}",
        "a${robot.annotations['ip']}b",
    ]
)
KEYS = st.sampled_from(["rate", "gain", "ip", "frame"])
PARAMETERS = st.recursive(
    st.one_of(st.integers(0, 3), VALUES),
    lambda inner: st.dictionaries(KEYS, inner, min_size=1, max_size=2),
    max_leaves=4,
).map(
    lambda doc: (
        yaml.safe_dump({"driver": {"ros__parameters": doc}}) if isinstance(doc, dict) else "driver: 1\n"
    )
)
COMPONENT_NAMES = st.sampled_from(["lidar", "slam", "executor", "legs", "ghost"])
SELECTORS = st.one_of(
    st.sampled_from(MODELS).map(lambda m: {"matchLabels": {"coral.dev/model": m}}),
    st.just({"matchLabels": {"fleet": "a"}}),
    st.just({"matchExpressions": [{"key": "site", "operator": "Exists"}]}),
)


@st.composite
def overrides(draw: st.DrawFn) -> list[dict[str, Any]]:
    names = draw(st.lists(st.sampled_from(["a", "b", "c", "d"]), unique=True, max_size=4))
    result = []
    for name in names:
        override: dict[str, Any] = {"name": name, "robots": draw(SELECTORS)}
        if draw(st.booleans()):
            override["parameters"] = draw(PARAMETERS)
        if draw(st.booleans()):
            override["env"] = [{"name": draw(st.sampled_from(["A", "IP"])), "value": draw(VALUES)}]
        if draw(st.booleans()):
            override["images"] = {
                draw(COMPONENT_NAMES): "img:" + draw(st.sampled_from(["1", "2", "${robot.name}"]))
            }
        if draw(st.booleans()):
            override["remove"] = draw(st.lists(COMPONENT_NAMES, unique=True, max_size=2))
        if draw(st.booleans()):
            kind = draw(st.sampled_from(["drivers", "skillsets", "executors"]))
            override["add"] = {kind: [{"name": draw(COMPONENT_NAMES), "image": "add:1"}]}
        if draw(st.booleans()):
            override["tree"] = {
                "inline": draw(st.sampled_from([TREE, BROKEN_TREE, TREE.replace("Sequence", "Fallback")]))
            }
        result.append(override)
    return result


@st.composite
def fleets(draw: st.DrawFn) -> list[RobotNode]:
    robots = []
    for i in range(draw(st.integers(1, 6))):
        labels = {"coral.dev/robot": f"r{i}", "fleet": "a", "coral.dev/model": draw(st.sampled_from(MODELS))}
        if draw(st.booleans()):
            labels["site"] = draw(st.sampled_from(["north", "south"]))
        annotations = {"ip": f"10.0.0.{i}"} if draw(st.booleans()) else {}
        robots.append(
            RobotNode(node_name=f"n{i}", robot=f"r{i}", labels=labels, ready=True, annotations=annotations)
        )
    return robots


def _plan(spec: dict[str, Any], robots: list[RobotNode]) -> system_pass.SystemPlan:
    return plan_pass(spec, robots, name="s")


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rules=overrides(), robots=fleets())
def test_every_robot_is_configured_or_named_with_its_field(
    rules: list[dict[str, Any]], robots: list[RobotNode]
) -> None:
    spec = {**copy.deepcopy(BASE_SPEC), "overrides": rules, "rollout": {"maxUnavailable": "100%"}}
    try:
        CoralSystemSpec.model_validate(spec)
    except ValidationError:
        event("refused by the schema")
        return  # refused at admission, with the schema's messages (tested with the schema)
    plan = _plan(spec, robots)
    assert plan.problem is None, plan.problem
    created = {m["spec"]["robot"]: m["spec"] for m in plan.changes.create}
    failed = {e.robot: e for e in plan.config_errors}
    assert set(created) | set(failed) == {r.robot for r in robots}
    assert not set(created) & set(failed)
    event("some robots named" if failed else "every robot configured")
    config_maps = {cm["metadata"]["name"]: cm["data"] for cm in plan.config_maps}
    for instance in created.values():
        CoralInstanceSpec.model_validate(instance)
        tree = config_maps[instance["tree"]["configMap"]]
        assert (
            validation.validate_tree(tree["tree.xml"], "tree.xml", instance["tree"].get("mainTreeId"), tree)
            == []
        )
        params = config_maps[instance["parameters"]["configMap"]]["params.yaml"]
        assert validation.validate_parameters(params, "params.yaml") == []
    if failed:
        problem = system_pass.config_problem(plan)
        assert problem is not None
        for robot, error in list(failed.items())[:10]:
            assert error.field.startswith("spec.overrides") and error.message
            assert f"robot {robot}: {error.field}" in problem.message
    reordered = _plan({**spec, "overrides": rules[::-1]}, robots)
    assert {m["spec"]["robot"]: m["spec"]["configHash"] for m in reordered.changes.create} == {
        robot: instance["configHash"] for robot, instance in created.items()
    }
    assert {e.robot for e in reordered.config_errors} == set(failed)
