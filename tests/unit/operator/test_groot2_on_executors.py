"""An executor's `groot2` field (issue 49): what its pod runs, what the policy allows, what its
CoralInstance says, and how `coral groot2` finds the pod. Pure, no cluster."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from coral_operator import config, groot2_target
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import GROOT2_PORTS_APART, CoralSystemSpec
from coral_operator.planning import instances, pods, policy
from coral_operator.status import instance_status
from operator_specs import BASE_SPEC, robot, view_with_pods_running
from pydantic import ValidationError

POD_NETWORK = {"network": "Pod"}


def _spec(*executors: dict[str, Any], **top: Any) -> dict[str, Any]:
    raw = copy.deepcopy(BASE_SPEC) | {"ros": POD_NETWORK}
    raw["executors"] = [{"name": "executor", "image": "example/executor:1"} | e for e in executors] or raw[
        "executors"
    ]
    raw.update(top)
    return raw


def _executor_container(raw: dict[str, Any]) -> dict[str, Any]:
    template = instances.build_template(CoralSystemSpec.model_validate(raw), "t", "p")
    spec = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    built = pods.build_pods(spec=spec, instance="sys-r1", namespace="ns", instance_uid="u")
    containers = [c for pod in built for c in pod["spec"]["containers"]]
    return next(c for c in containers if c["name"] == "executor")


def _command_line(container: dict[str, Any]) -> list[str]:
    return container.get("command", []) + container.get("args", [])


# ---- what the executor's pod runs


@pytest.mark.parametrize(
    ("story", "groot2", "flags"),
    [
        ("the defaults publish on 1667, hooks refused", {}, ["--groot2-port", "1667"]),
        (
            "every setting",
            {"port": 7000, "allowHooks": True, "waitForClientSeconds": 30},
            ["--groot2-port", "7000", "--groot2-allow-hooks", "--groot2-wait", "30"],
        ),
    ],
)
def test_the_executor_is_started_with_the_groot2_flags(story: str, groot2: dict, flags: list[str]) -> None:
    command = _executor_container(_spec({"groot2": groot2}))["command"]
    assert command[:3] == ["python", "-m", "coral.executor"]
    assert command[-len(flags) :] == flags


def test_an_executor_without_groot2_publishes_nothing() -> None:
    assert not any(part.startswith("--groot2") for part in _command_line(_executor_container(_spec())))


def test_the_flags_follow_the_users_own_arguments() -> None:
    """With args of its own the image's entrypoint (`python -m coral.executor`) runs them; the flags
    must reach it all the same."""
    container = _executor_container(
        _spec({"args": ["--tree", "/etc/coral/tree.xml"], "groot2": {"port": 2000}})
    )
    assert "command" not in container
    assert container["args"] == ["--tree", "/etc/coral/tree.xml", "--groot2-port", "2000"]


def test_a_users_command_keeps_its_own_words_and_gets_the_flags_as_arguments() -> None:
    container = _executor_container(_spec({"command": ["my-executor"], "groot2": {"port": 2000}}))
    assert container["command"] == ["my-executor"]
    assert container["args"] == ["--groot2-port", "2000"]


def test_the_publisher_is_never_told_to_bind_beyond_the_pods_loopback() -> None:
    line = _command_line(_executor_container(_spec({"groot2": {"allowHooks": True}})))
    assert "--groot2-host" not in line


# ---- what the spec may say


@pytest.mark.parametrize(
    ("story", "groot2"),
    [
        ("a port only root may bind", {"port": 80}),
        ("a port without a next one", {"port": 65535}),
        ("a wait beyond an hour", {"waitForClientSeconds": 3601}),
    ],
)
def test_groot2_settings_out_of_range_are_refused(story: str, groot2: dict) -> None:
    with pytest.raises(ValidationError, match="groot2"):
        CoralSystemSpec.model_validate(_spec({"groot2": groot2}))


def test_two_executors_whose_port_pairs_overlap_are_refused() -> None:
    second = {"name": "second", "image": "example/executor:1"}
    with pytest.raises(ValidationError, match="at least 2 apart"):
        CoralSystemSpec.model_validate(_spec({"groot2": {"port": 1667}}, second | {"groot2": {"port": 1668}}))
    assert CoralSystemSpec.model_validate(
        _spec({"groot2": {"port": 1667}}, second | {"groot2": {"port": 1669}})
    )
    assert "2 apart" in GROOT2_PORTS_APART


def test_groot2_is_a_field_of_executors_only() -> None:
    raw = _spec()
    raw["drivers"][0]["groot2"] = {"port": 1667}
    with pytest.raises(ValidationError, match="groot2"):
        CoralSystemSpec.model_validate(raw)


# ---- the privilege policy

HOOKS_DENIED = "spec.executors[0] (executor): groot2.allowHooks is not allowed in namespace robots"


@pytest.mark.parametrize(
    ("story", "executor", "environment", "expected"),
    [
        ("watching needs no permission", {"groot2": {"port": 1667}}, {}, []),
        ("hooks are closed by default", {"groot2": {"allowHooks": True}}, {}, [HOOKS_DENIED]),
        (
            "hooks opened for the namespace",
            {"groot2": {"allowHooks": True}},
            {"CORAL_POLICY_GROOT2_HOOKS_NAMESPACES": "robots"},
            [],
        ),
        (
            "hooks opened for every namespace",
            {"groot2": {"allowHooks": True}},
            {"CORAL_POLICY_GROOT2_HOOKS_NAMESPACES": "*"},
            [],
        ),
        (
            "hooks opened elsewhere only",
            {"groot2": {"allowHooks": True}},
            {"CORAL_POLICY_GROOT2_HOOKS_NAMESPACES": "lab"},
            [HOOKS_DENIED],
        ),
        (
            "the flag written into the arguments by hand",
            {"args": ["--tree", "/etc/coral/tree.xml", "--groot2-port", "1667", " --groot2-allow-hooks"]},
            {},
            [
                "spec.executors[0] (executor): args holds --groot2-allow-hooks, which is not allowed in "
                "namespace robots"
            ],
        ),
        (
            "the flag written into the command by hand",
            {"command": ["python", "-m", "coral.executor", "--groot2-allow-hooks"]},
            {},
            [
                "spec.executors[0] (executor): command holds --groot2-allow-hooks, which is not allowed in "
                "namespace robots"
            ],
        ),
    ],
)
def test_the_policy_decides_where_hooks_may_be_enabled(
    story: str, executor: dict, environment: dict[str, str], expected: list[str]
) -> None:
    spec = CoralSystemSpec.model_validate(_spec(executor))
    assert policy.evaluate_policy("robots", spec, config.from_environment(environment).policy) == expected


def test_the_default_policy_opens_hooks_nowhere() -> None:
    assert not policy.Policy().groot2_hooks_namespaces
    assert config.from_environment({}).policy.groot2_hooks_namespaces == frozenset()


# ---- what the CoralInstance says


def test_the_instance_says_which_port_its_executor_publishes_on() -> None:
    raw = _spec({"groot2": {"port": 4000}})
    entries = instance_status.build_components(view_with_pods_running(raw))
    by_name = {e["name"]: e for e in entries}
    assert by_name["executor"]["groot2Port"] == 4000
    assert "groot2Port" not in by_name["lidar"] and "groot2Port" not in by_name["slam"]


def test_an_instance_without_groot2_names_no_port() -> None:
    entries = instance_status.build_components(view_with_pods_running(_spec()))
    assert all("groot2Port" not in e for e in entries)


# ---- how `coral groot2` finds the pod


def _instance(robot_name: str, *components: dict[str, Any], declared: bool = True) -> dict[str, Any]:
    executors = [{"name": "executor", "image": "x", **({"groot2": {"port": 1667}} if declared else {})}]
    return {
        "spec": {"system": "mission", "robot": robot_name, "executors": executors},
        "status": {"components": list(components)},
    }


SERVED = {
    "name": "executor",
    "role": "executor",
    "pod": "mission-r1-executor-abc",
    "phase": "Running",
    "groot2Port": 1667,
}


def _find(instances_: list[dict[str, Any]], robot_name: str = "r1", executor: str | None = None) -> Any:
    return groot2_target.find_target(
        system="mission", robot=robot_name, namespace="lab", instances=instances_, executor=executor
    )


def test_the_target_is_the_executors_pod_and_the_port_its_instance_names() -> None:
    target = _find([_instance("r0"), _instance("r1", {"name": "lidar", "role": "driver"}, SERVED)])
    assert target == groot2_target.Target(
        namespace="lab", pod="mission-r1-executor-abc", port=1667, executor="executor"
    )


@pytest.mark.parametrize(
    ("story", "instances_", "robot_name", "executor", "message"),
    [
        (
            "a robot the system does not match",
            [_instance("r0", SERVED), _instance("r2", SERVED)],
            "r1",
            None,
            "robot r1 is not matched by coralsystem/mission in namespace lab (its robots: r0, r2)",
        ),
        (
            "a system without groot2 says how to enable it",
            [_instance("r1", {k: v for k, v in SERVED.items() if k != "groot2Port"}, declared=False)],
            "r1",
            None,
            "does not publish its trees over Groot2: enable it with `groot2: {port: 1667}`",
        ),
        (
            "an instance the operator has not reported yet",
            [_instance("r1")],
            "r1",
            None,
            "does not report its executor's pod yet",
        ),
        (
            "an executor waiting for its startup stage",
            [_instance("r1", {**SERVED, "pod": None, "phase": "Waiting"})],
            "r1",
            None,
            "has no pod yet (Waiting",
        ),
        (
            "an executor named that does not publish",
            [_instance("r1", SERVED)],
            "r1",
            "other",
            "executor other of coralsystem/mission has no groot2 (those with it: executor)",
        ),
        (
            "several executors and none named",
            [_instance("r1", SERVED, {**SERVED, "name": "second", "groot2Port": 1669})],
            "r1",
            None,
            "several executors with groot2 (executor, second): name one with --executor",
        ),
    ],
)
def test_unreachable_trees_are_named_with_what_to_do(
    story: str, instances_: list[dict], robot_name: str, executor: str | None, message: str
) -> None:
    with pytest.raises(groot2_target.TargetError, match=None) as caught:
        _find(instances_, robot_name, executor)
    assert message in str(caught.value)


@pytest.mark.parametrize(
    ("phase", "running", "message"),
    [
        (None, {}, "no longer exists"),
        ("Pending", {}, "is not running yet (Pending)"),
        ("Running", {"executor": False}, "is not running yet (its container not running)"),
    ],
)
def test_a_pod_that_is_not_running_is_refused(phase: str | None, running: dict, message: str) -> None:
    target = groot2_target.Target(namespace="lab", pod="p", port=1667, executor="executor")
    with pytest.raises(groot2_target.TargetError) as caught:
        groot2_target.check_running(target, phase, running)
    assert message in str(caught.value)
    groot2_target.check_running(target, "Running", {"executor": True})


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["mission"], "give both SYSTEM and ROBOT, or neither"),
        (["mission", "r1", "--host", "10.0.0.1"], "--host and SYSTEM ROBOT exclude each other"),
    ],
)
def test_tree_watch_refuses_a_half_given_robot(arguments: list[str], message: str) -> None:
    from click.testing import CliRunner
    from coral_operator.tree_cli import tree_group

    result = CliRunner().invoke(tree_group, ["watch", *arguments, "--once"])
    assert result.exit_code == 2
    assert message in result.output
