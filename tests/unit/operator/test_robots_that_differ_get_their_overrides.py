"""Per-robot overrides: what each robot runs, in what precedence, and what a change rolls out to.

The table states the precedence once per field (parameters, env, images, components, tree files,
Node values); the fleet tests run whole system passes over robots of three models.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable
from typing import Any

import pytest
import yaml
from coral_core import names
from coral_operator import config_cli, robot_config
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import effective, provenance, system_pass
from coral_operator.planning.observed import ObservedInstance, RobotNode
from coral_operator.planning.overrides import BaseConfig, ConfigError, EffectiveConfig, effective_config
from coral_operator.status.conditions import Reason
from operator_specs import BASE_SPEC, TREE, observed_instance, plan_pass

NAV = '<root BTCPP_format="4"><BehaviorTree ID="Nav"><AlwaysSuccess/></BehaviorTree></root>'
ARM_TREE = TREE.replace("<AlwaysSuccess/>", "<AlwaysFailure/>")


def _node(name: str, model: str, **annotations: str) -> RobotNode:
    return RobotNode(
        node_name=name,
        robot=name,
        labels={"coral.dev/robot": name, "fleet": "a", "coral.dev/model": model},
        ready=True,
        annotations=annotations,
    )


def _on(model: str, name: str | None = None, **fields: Any) -> dict[str, Any]:
    return {"name": name or model, "robots": {"matchLabels": {"coral.dev/model": model}}, **fields}


def _resolve(overrides: list[dict[str, Any]], robot: RobotNode) -> EffectiveConfig | ConfigError:
    spec = CoralSystemSpec.model_validate({**copy.deepcopy(BASE_SPEC), "overrides": overrides})
    base = BaseConfig.of_spec(spec, TREE, spec.parameters.inline or "")
    return effective_config(base, spec.overrides, robot)


def _params(config: EffectiveConfig) -> Any:
    return yaml.safe_load(config.parameters)


def _component(config: EffectiveConfig, name: str) -> Any:
    return next(
        c for kind in ("drivers", "skillsets", "executors") for c in getattr(config, kind) if c.name == name
    )


def _env(config: EffectiveConfig, name: str) -> dict[str, str]:
    return {e.name: e.value for e in _component(config, name).env}


Check = Callable[[EffectiveConfig], Any]
CASES: list[tuple[str, list[dict[str, Any]], RobotNode, Check, Any]] = [
    (
        "a robot no override matches runs the system's spec as it is",
        [_on("arm", images={"executor": "x/arm:1"})],
        _node("r1", "spot"),
        lambda c: (c.parameters, c.applied, _component(c, "executor").image),
        (BASE_SPEC["parameters"]["inline"], (), "example/executor:1"),
    ),
    (
        "override parameters merge key by key onto the system's",
        [_on("spot", parameters="driver:\n  ros__parameters:\n    gain: 2\n")],
        _node("r1", "spot"),
        _params,
        {"driver": {"ros__parameters": {"rate": 10, "gain": 2}}},
    ),
    (
        "an override parameter replaces the system's value of the same key",
        [_on("spot", parameters="driver:\n  ros__parameters:\n    rate: 50\n")],
        _node("r1", "spot"),
        _params,
        {"driver": {"ros__parameters": {"rate": 50}}},
    ),
    (
        "a list in an override replaces the system's list whole",
        [_on("spot", parameters="driver:\n  ros__parameters:\n    rate: [1, 2]\n")],
        _node("r1", "spot"),
        lambda c: _params(c)["driver"]["ros__parameters"]["rate"],
        [1, 2],
    ),
    (
        "two overrides setting different parameters both apply",
        [
            _on("spot", parameters="driver:\n  ros__parameters:\n    gain: 2\n"),
            {"name": "site-b", "robots": {"matchLabels": {"fleet": "a"}}, "parameters": "slam:\n  x: 1\n"},
        ],
        _node("r1", "spot"),
        lambda c: (_params(c)["slam"], _params(c)["driver"]["ros__parameters"]["gain"], c.applied),
        ({"x": 1}, 2, ("spot", "site-b")),
    ),
    (
        "env is set in every component and replaces a variable of the same name",
        [_on("spot", env=[{"name": "MODE", "value": "fast"}])],
        _node("r1", "spot"),
        lambda c: [_env(c, n).get("MODE") for n in ("lidar", "slam", "executor")],
        ["fast", "fast", "fast"],
    ),
    (
        "images replace a component's image on the matched robots only",
        [_on("spot", images={"slam": "example/slam:2"})],
        _node("r1", "spot"),
        lambda c: (_component(c, "slam").image, _component(c, "lidar").image),
        ("example/slam:2", "example/lidar:1"),
    ),
    (
        "components are removed, then added, then given images and env",
        [
            _on(
                "spot",
                remove=["lidar"],
                add={"drivers": [{"name": "legs", "image": "example/legs:1"}]},
                images={"legs": "example/legs:2"},
                env=[{"name": "A", "value": "1"}],
            )
        ],
        _node("r1", "spot"),
        lambda c: ([d.name for d in c.drivers], _component(c, "legs").image, _env(c, "legs")),
        (["legs"], "example/legs:2", {"A": "1"}),
    ),
    (
        "a component removed and added by the same override is replaced",
        [_on("spot", remove=["slam"], add={"skillsets": [{"name": "slam", "image": "other/slam:1"}]})],
        _node("r1", "spot"),
        lambda c: [(s.name, s.image) for s in c.skillsets],
        [("slam", "other/slam:1")],
    ),
    (
        "tree files are added and the main tree replaced",
        [_on("arm", tree={"inline": ARM_TREE, "files": {"nav.xml": NAV}})],
        _node("r1", "arm"),
        lambda c: (c.tree, c.tree_files, sorted(c.changed)),
        (ARM_TREE, {"nav.xml": NAV}, ["tree"]),
    ),
    (
        "Node values are substituted into parameters, env and images",
        [
            _on(
                "spot",
                parameters="driver:\n  ros__parameters:\n    ip: ${robot.annotations['coral.dev/ip']}\n",
                env=[{"name": "ROBOT", "value": "${robot.name}-${robot.labels['coral.dev/model']}"}],
                images={"lidar": "example/lidar:${robot.annotations['lidar-tag']}"},
            )
        ],
        _node("r7", "spot", **{"coral.dev/ip": "10.0.0.7", "lidar-tag": "v3"}),
        lambda c: (
            _params(c)["driver"]["ros__parameters"]["ip"],
            _env(c, "executor")["ROBOT"],
            _component(c, "lidar").image,
        ),
        ("10.0.0.7", "r7-spot", "example/lidar:v3"),
    ),
    (
        "$${ is a literal ${",
        [_on("spot", env=[{"name": "A", "value": "$${robot.name}"}])],
        _node("r1", "spot"),
        lambda c: _env(c, "slam")["A"],
        "${robot.name}",
    ),
    (
        "two overrides agreeing on a value do not conflict",
        [_on("spot", images={"slam": "s:2"}), _on("spot", "also-spot", images={"slam": "s:2"})],
        _node("r1", "spot"),
        lambda c: _component(c, "slam").image,
        "s:2",
    ),
]

ERRORS: list[tuple[str, list[dict[str, Any]], RobotNode, tuple[str, ...]]] = [
    (
        "two overrides setting one parameter differently conflict, naming both",
        [
            _on("spot", parameters="driver:\n  ros__parameters:\n    rate: 1\n"),
            _on("spot", "lab", parameters="driver:\n  ros__parameters:\n    rate: 2\n"),
        ],
        _node("r1", "spot"),
        ("spec.overrides[lab].parameters.driver.ros__parameters.rate", "override spot"),
    ),
    (
        "a parameter mapping against a scalar of another override conflicts",
        [
            _on("spot", parameters="driver:\n  ros__parameters: 1\n"),
            _on("spot", "lab", parameters="driver:\n  ros__parameters:\n    rate: 2\n"),
        ],
        _node("r1", "spot"),
        ("spec.overrides[lab].parameters.driver.ros__parameters.rate", "override spot"),
    ),
    (
        "two overrides setting one env variable differently conflict",
        [
            _on("spot", env=[{"name": "A", "value": "1"}]),
            _on("spot", "lab", env=[{"name": "A", "value": "2"}]),
        ],
        _node("r1", "spot"),
        ("spec.overrides[lab].env[A]", "override spot"),
    ),
    (
        "two overrides giving one component different images conflict",
        [_on("spot", images={"slam": "a:1"}), _on("spot", "lab", images={"slam": "a:2"})],
        _node("r1", "spot"),
        ("spec.overrides[lab].images[slam]", "override spot"),
    ),
    (
        "two overrides giving one tree file different contents conflict",
        [
            _on("spot", tree={"files": {"nav.xml": NAV}}),
            _on("spot", "lab", tree={"files": {"nav.xml": TREE}}),
        ],
        _node("r1", "spot"),
        ("spec.overrides[lab].tree.files[nav.xml]", "override spot"),
    ),
    (
        "a missing label names the robot, the field and the key",
        [_on("spot", env=[{"name": "IP", "value": "${robot.labels['site']}"}])],
        _node("r9", "spot"),
        ("robot r9", "spec.overrides[spot].env[IP]", "no label", "site"),
    ),
    (
        "a missing annotation in parameters names the field",
        [_on("spot", parameters="driver:\n  ip: ${robot.annotations['ip']}\n")],
        _node("r9", "spot"),
        ("robot r9", "spec.overrides[spot].parameters.driver.ip", "no annotation"),
    ),
    (
        "an unknown reference is named with the syntax that works",
        [_on("spot", env=[{"name": "IP", "value": "${node.name}"}])],
        _node("r1", "spot"),
        ("spec.overrides[spot].env[IP]", "${robot.name}"),
    ),
    (
        "an image for a component the robot does not run is refused",
        [_on("spot", images={"arm": "a:1"})],
        _node("r1", "spot"),
        ("spec.overrides[spot].images[arm]", "no component 'arm'"),
    ),
    (
        "removing the only executor is refused",
        [_on("spot", remove=["executor"])],
        _node("r1", "spot"),
        ("at least one is required",),
    ),
    (
        "adding a component the robot already runs is refused",
        [_on("spot", add={"skillsets": [{"name": "slam", "image": "x:1"}]})],
        _node("r1", "spot"),
        ("spec.overrides[spot].add.skillsets[slam]", "already runs"),
    ),
]


@pytest.mark.parametrize(
    ("overrides", "robot", "check", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_precedence_and_merge(
    overrides: list[dict[str, Any]], robot: RobotNode, check: Check, expected: Any
) -> None:
    config = _resolve(overrides, robot)
    assert isinstance(config, EffectiveConfig), config
    assert check(config) == expected


@pytest.mark.parametrize(("overrides", "robot", "words"), [c[1:] for c in ERRORS], ids=[c[0] for c in ERRORS])
def test_refusals_name_the_robot_and_the_field(
    overrides: list[dict[str, Any]], robot: RobotNode, words: tuple[str, ...]
) -> None:
    config = _resolve(overrides, robot)
    assert isinstance(config, ConfigError), config
    for word in words:
        assert word in str(config)


def test_override_order_does_not_change_what_a_robot_runs() -> None:
    overrides = [
        _on("spot", parameters="a:\n  b: 1\n", env=[{"name": "A", "value": "1"}]),
        {
            "name": "all",
            "robots": {"matchLabels": {"fleet": "a"}},
            "parameters": "a:\n  c: 2\n",
            "images": {"slam": "s:9"},
        },
    ]
    forward = _resolve(overrides, _node("r1", "spot"))
    backward = _resolve(overrides[::-1], _node("r1", "spot"))
    assert isinstance(forward, EffectiveConfig) and isinstance(backward, EffectiveConfig)
    assert _params(forward) == _params(backward)
    assert [c.to_wire() for c in forward.skillsets] == [c.to_wire() for c in backward.skillsets]


# --- whole system passes over a fleet of three models -------------------------------------------

FLEET = (
    [_node(f"spot-{i}", "spot") for i in range(3)]
    + [_node(f"arm-{i}", "arm") for i in range(2)]
    + [_node("server-0", "server", **{"coral.dev/ip": "10.0.0.1"})]
)


def _fleet_spec(spot_rate: int = 20) -> dict[str, Any]:
    return {
        **copy.deepcopy(BASE_SPEC),
        "rollout": {"maxUnavailable": "100%"},
        "overrides": [
            _on(
                "spot",
                parameters=f"driver:\n  ros__parameters:\n    rate: {spot_rate}\n",
                images={"lidar": "x/spot-lidar:1"},
            ),
            _on(
                "arm",
                remove=["lidar"],
                add={"drivers": [{"name": "gripper", "image": "x/gripper:1"}]},
                tree={"inline": ARM_TREE},
            ),
            _on("server", env=[{"name": "IP", "value": "${robot.annotations['coral.dev/ip']}"}]),
        ],
    }


def _observe(
    spec: dict[str, Any], instances: list[ObservedInstance], stored: list[Any]
) -> system_pass.SystemPlan:
    return plan_pass(spec, FLEET, instances, stored)


def _applied(plan: system_pass.SystemPlan, before: list[ObservedInstance]) -> list[ObservedInstance]:
    """The instances once `plan` is written and every robot reports Ready."""
    by_name = {i.name: i for i in before}
    for manifest in plan.changes.create + plan.changes.update:
        by_name[manifest["metadata"]["name"]] = observed_instance(manifest)
    return [dataclasses.replace(i, ready=True) for i in by_name.values()]


def _deployed(spec: dict[str, Any]) -> tuple[list[ObservedInstance], list[Any]]:
    plan = _observe(spec, [], [])
    return _applied(plan, []), plan.stored_after


def _config_map(plan: system_pass.SystemPlan, name: str) -> dict[str, str]:
    return next(cm["data"] for cm in plan.config_maps if cm["metadata"]["name"] == name)


def test_each_model_gets_its_components_parameters_and_tree() -> None:
    plan = _observe(_fleet_spec(), [], [])
    assert not plan.config_errors
    specs = {m["spec"]["robot"]: m["spec"] for m in plan.changes.create}
    assert {d["name"]: d["image"] for d in specs["spot-0"]["drivers"]} == {"lidar": "x/spot-lidar:1"}
    assert [d["name"] for d in specs["arm-1"]["drivers"]] == ["gripper"]
    assert [d["name"] for d in specs["server-0"]["drivers"]] == ["lidar"]
    assert {"name": "IP", "value": "10.0.0.1"} in specs["server-0"]["executors"][0]["env"]
    spot_params = _config_map(plan, specs["spot-0"]["parameters"]["configMap"])["params.yaml"]
    assert yaml.safe_load(spot_params)["driver"]["ros__parameters"]["rate"] == 20
    assert _config_map(plan, specs["arm-0"]["tree"]["configMap"])["tree.xml"] == ARM_TREE
    hashes = {robot: spec["configHash"] for robot, spec in specs.items()}
    assert len(set(hashes.values())) == 3  # one per model: robots of a model share their configuration
    assert hashes["spot-0"] == hashes["spot-2"] and hashes["arm-0"] == hashes["arm-1"]
    assert {spec["revision"] for spec in specs.values()} == {plan.rollout.target}  # type: ignore[union-attr]


def test_changing_one_models_override_rolls_out_to_that_model_only() -> None:
    instances, stored = _deployed(_fleet_spec(spot_rate=20))
    plan = _observe(_fleet_spec(spot_rate=30), instances, stored)
    assert plan.rollout is not None
    assert set(plan.rollout.moves) == {r.robot for r in FLEET}
    before = {i.robot: i.spec for i in instances}
    after = {m["spec"]["robot"]: m["spec"] for m in plan.changes.update}
    # Every robot is at the new revision, but only the spots' configuration changed.
    assert set(after) == {r.robot for r in FLEET}
    changed = {robot for robot, spec in after.items() if spec["configHash"] != before[robot]["configHash"]}
    assert changed == {"spot-0", "spot-1", "spot-2"}
    for robot in ("arm-0", "server-0"):
        assert {**after[robot], "revision": None} == {**before[robot], "revision": None}


def test_an_unchanged_robot_costs_no_rollout_budget() -> None:
    spec = _fleet_spec(spot_rate=20)
    instances, stored = _deployed(spec)
    changed = _fleet_spec(spot_rate=30)
    changed["rollout"] = {"maxUnavailable": 1}
    plan = _observe(changed, instances, stored)
    assert plan.rollout is not None
    # The other models move at once; of the spots, one at a time.
    assert len([robot for robot in plan.rollout.moves if robot.startswith("spot-")]) == 1
    assert plan.rollout.status.counts.updated == len(FLEET) - 3


def test_a_robot_with_a_broken_override_keeps_what_it_runs_and_is_named() -> None:
    instances, stored = _deployed(_fleet_spec())
    broken = _fleet_spec()
    broken["overrides"][2]["env"] = [{"name": "IP", "value": "${robot.annotations['coral.dev/vpn-ip']}"}]
    plan = _observe(broken, instances, stored)
    assert [e.robot for e in plan.config_errors] == ["server-0"]
    assert "server-0" not in {m["spec"]["robot"] for m in plan.changes.update}
    assert not plan.changes.delete and not plan.changes.retire
    problem = system_pass.config_problem(plan)
    assert problem is not None and problem.reason == Reason.INVALID_ROBOT_CONFIG
    assert "robot server-0: spec.overrides[server].env[IP]" in problem.message


def test_a_robot_matched_by_conflicting_overrides_is_not_deployed_and_the_system_names_both() -> None:
    spec = _fleet_spec()
    spec["overrides"].append(_on("spot", "lab", images={"lidar": "x/lab-lidar:1"}))
    plan = _observe(spec, [], [])
    assert sorted(e.robot for e in plan.config_errors) == ["spot-0", "spot-1", "spot-2"]
    assert {m["spec"]["robot"] for m in plan.changes.create} == {"arm-0", "arm-1", "server-0"}
    message = system_pass.config_problem(plan).message  # type: ignore[union-attr]
    assert "spec.overrides[lab].images[lidar]" in message and "override spot" in message


def test_a_broken_tree_in_an_override_names_the_robot_and_the_line() -> None:
    spec = _fleet_spec()
    spec["overrides"][1]["tree"] = {"inline": '<root BTCPP_format="4">\n<BehaviorTree ID="Main">\n<Nope'}
    plan = _observe(spec, [], [])
    assert sorted(e.robot for e in plan.config_errors) == ["arm-0", "arm-1"]
    assert "spec.overrides[arm].tree" in str(plan.config_errors[0])
    assert "tree.xml for robot arm-0:3" in str(plan.config_errors[0])


def test_systems_without_overrides_keep_their_revision() -> None:
    spec = copy.deepcopy(BASE_SPEC)
    plan = _observe(spec, [], [])
    revision = plan.rollout.target  # type: ignore[union-attr]
    assert all(m["spec"]["configHash"] == revision for m in plan.changes.create)
    assert names.LABEL_SYSTEM  # the instance labels are the system's, as without overrides
    assert effective.OVERRIDES not in plan.stored_after[0].template


def test_an_instance_with_its_overrides_is_served_and_one_edited_by_hand_is_not() -> None:
    plan = _observe(_fleet_spec(), [], [])
    manifest = next(m for m in plan.changes.create if m["spec"]["robot"] == "arm-0")
    spec = CoralInstanceSpec.model_validate(manifest["spec"])
    node = next(n for n in FLEET if n.robot == "arm-0")
    assert provenance.evaluate_revision(spec, plan.stored_after, node) is None
    edited = spec.model_copy(
        update={"drivers": [d.model_copy(update={"image": "evil:1"}) for d in spec.drivers]}
    )
    assert "differs from revision" in (provenance.evaluate_revision(edited, plan.stored_after, node) or "")
    as_a_spot = dataclasses.replace(node, labels={**node.labels, "coral.dev/model": "spot"})
    assert provenance.evaluate_revision(spec, plan.stored_after, as_a_spot) is not None


def _system_body(spec: dict[str, Any]) -> dict[str, Any]:
    return {"metadata": {"name": "site", "namespace": "ns", "uid": "u-site"}, "spec": spec}


def test_coral_config_shows_what_a_robot_runs_with_the_operators_hash() -> None:
    plan = _observe(_fleet_spec(), [], [])
    instance = next(m for m in plan.changes.create if m["spec"]["robot"] == "server-0")
    server = next(n for n in FLEET if n.robot == "server-0")
    said = robot_config.explain(
        system=_system_body(_fleet_spec()),
        node=server,
        tree=TREE,
        parameters=BASE_SPEC["parameters"]["inline"],
        instance=instance,
    )
    assert said.valid and said.runs_it and said.overrides == ("server",)
    text = config_cli.render(said)
    assert "running: this configuration" in text
    assert "executor  executor             example/executor:1  [IP=10.0.0.1]" in text
    assert "rate: 10" in text and "<AlwaysSuccess/>" in text


def test_coral_config_names_what_is_wrong_and_that_the_robot_keeps_what_it_runs() -> None:
    spec = _fleet_spec()
    spec["overrides"][2]["env"] = [{"name": "IP", "value": "${robot.annotations['vpn']}"}]
    server = next(n for n in FLEET if n.robot == "server-0")
    said = robot_config.explain(system=_system_body(spec), node=server, tree=TREE, parameters="a: 1\n")
    assert not said.valid
    text = config_cli.render(said)
    assert "INVALID" in text and "robot server-0: spec.overrides[server].env[IP]" in text
    assert "running: no CoralInstance yet" in text


def test_an_override_naming_a_main_tree_the_document_lacks_is_refused_for_its_robots() -> None:
    spec = _fleet_spec()
    spec["overrides"][0]["tree"] = {"mainTreeId": "Nowhere"}
    plan = _observe(spec, [], [])
    assert sorted(e.robot for e in plan.config_errors) == ["spot-0", "spot-1", "spot-2"]
    assert "Nowhere" in str(plan.config_errors[0])


def test_an_undo_returns_each_robot_to_what_the_earlier_revision_gave_it() -> None:
    first, stored = _deployed(_fleet_spec(spot_rate=20))
    change = _observe(_fleet_spec(spot_rate=30), first, stored)
    second = _applied(change, first)
    newest = change.rollout.target  # type: ignore[union-attr]
    undone = {names.ANNOTATION_ROLLOUT_UNDO: newest}
    undo = plan_pass(_fleet_spec(spot_rate=30), FLEET, second, change.stored_after, annotations=undone)
    assert undo.rollout is not None and undo.rollout.target != newest
    back = {m["spec"]["robot"]: m["spec"] for m in undo.changes.update}
    assert set(back) == {r.robot for r in FLEET}
    was = {i.robot: i.spec for i in first}
    for robot, spec in back.items():
        assert spec["configHash"] == was[robot]["configHash"]
    rate = yaml.safe_load(
        next(
            cm["data"]["params.yaml"]
            for cm in undo.config_maps
            if cm["metadata"]["name"] == back["spot-1"]["parameters"]["configMap"]
        )
    )["driver"]["ros__parameters"]["rate"]
    assert rate == 20


def test_components_an_override_adds_are_held_to_the_privilege_policy() -> None:
    spec = _fleet_spec()
    spec["overrides"][1]["add"]["drivers"][0]["privileged"] = True
    plan = plan_pass(spec, FLEET)
    assert plan.problem is not None and plan.problem.reason == Reason.POLICY_DENIED
    assert "spec.overrides[arm].add.drivers[0] (gripper)" in plan.problem.message
    assert not plan.changes.create


def test_a_robot_moved_at_once_is_not_written_again_before_the_watch_brings_it() -> None:
    instances, stored = _deployed(_fleet_spec(spot_rate=20))
    changed = _fleet_spec(spot_rate=30)
    changed["rollout"] = {"maxUnavailable": 1}
    first = _observe(changed, instances, stored)
    assert first.rollout is not None
    free = {r.robot for r in FLEET if not r.robot.startswith("spot-")}
    assert free <= set(first.rollout.moves), "remembered as moves, so a pass before the watch skips them"
    # The index still shows every robot as it was.
    again = plan_pass(
        changed,
        FLEET,
        instances,
        first.stored_after,
        expected=first.rollout.moves,
        previous_rollout=first.rollout.status,
    )
    assert not {m["spec"]["robot"] for m in again.changes.update} & free
    assert again.rollout is not None and again.rollout.status.counts.updated >= len(free)
