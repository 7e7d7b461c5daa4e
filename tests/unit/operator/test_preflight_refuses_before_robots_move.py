"""Preflight: a robot's effective tree against what its images declare, refused before any robot moves.

The declarations are those a skillset exports at runtime (its plugin manifest), carried in the
image's label; the system passes are whole `plan_system` passes over a fleet of three models.
"""

from __future__ import annotations

import copy
from typing import Any

import pytest
from coral.plugins import exporting
from coral.plugins.manifest import ComponentRef
from coral_core import bt, preflight
from coral_core.image_exports import EXPORTS_LABEL, DeclaredBehavior, ImageExports, from_labels
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import preflight as operator_preflight
from coral_operator.planning import system_pass
from coral_operator.planning.observed import RobotNode
from coral_operator.planning.preflight import ImageTable
from coral_operator.status.conditions import Reason
from coral_skillsets.examples import behaviors
from operator_specs import BASE_SPEC, plan_pass

SLAM = "reg.example/slam:1"
LIDAR = "reg.example/lidar:1"
ARM = "reg.example/arm:1"


@pytest.fixture(scope="module")
def examples(tmp_path_factory: pytest.TempPathFactory) -> ImageExports:
    """What the example skillset's image declares: its runtime manifest, through the label."""
    folder = exporting.export_plugin(
        tmp_path_factory.mktemp("plugins"),
        ComponentRef(name="examples", kind="skillset", node_name="examples"),
        [behaviors.Greet, behaviors.Count, behaviors.IsAtLeast, behaviors.WaitForCount],
    )
    manifest = exporting.manifests.parse_manifest((folder / "manifest.json").read_text(), "manifest.json")
    label = manifest.image_exports().to_label()
    declared = from_labels({EXPORTS_LABEL: label}, SLAM)
    assert declared is not None
    return declared


def _tree(*leaves: str) -> str:
    body = "\n".join(f"      {leaf}" for leaf in leaves)
    return (
        '<root BTCPP_format="4">\n  <BehaviorTree ID="Main">\n    <Sequence>\n'
        f"{body}\n    </Sequence>\n  </BehaviorTree>\n</root>\n"
    )


def _check(text: str, images: dict[str, ImageExports | None], version: str = "0.1.0") -> preflight.Verdict:
    return preflight.check_document(bt.load_tree_text(text, filename="mission.xml"), images, version)


def test_a_tree_using_only_declared_behaviors_and_ports_passes(examples: ImageExports) -> None:
    verdict = _check(
        _tree('<Greet who="crew" greeting="{g}"/>', '<IsAtLeast value="3" threshold="2"/>'), {SLAM: examples}
    )
    assert verdict.passed and verdict.undeclared == []


def test_a_behavior_no_image_exports_is_refused_with_file_line_and_the_images(examples: ImageExports) -> None:
    verdict = _check(_tree('<Greet who="crew"/>', "<Fly/>"), {SLAM: examples})
    assert verdict.problems == [f"mission.xml:5: behavior Fly is exported by none of the images {SLAM}"]


def test_a_port_the_image_does_not_declare_is_refused_naming_the_image(examples: ImageExports) -> None:
    verdict = _check(_tree('<Greet who="crew" loudness="11"/>'), {SLAM: examples})
    assert verdict.problems == [
        f"mission.xml:4: port [loudness] of Greet is not declared by image {SLAM} "
        "(it declares: who, greeting)"
    ]


def test_a_port_value_of_the_wrong_type_is_refused(examples: ImageExports) -> None:
    verdict = _check(_tree('<IsAtLeast value="3" threshold="many"/>'), {SLAM: examples})
    assert len(verdict.problems) == 1 and "mission.xml:4" in verdict.problems[0]
    assert "threshold" in verdict.problems[0] and SLAM in verdict.problems[0]


def test_an_image_of_another_coral_major_version_is_refused(examples: ImageExports) -> None:
    verdict = _check(_tree('<Greet who="crew"/>'), {SLAM: examples}, version="1.0.0")
    assert verdict.problems == [
        f"image {SLAM} was built for Coral 0.1.0; this is Coral 1.0.0 (major versions 0.1 and 1 differ)"
    ]
    # 0.x releases: the minor is the major (semver), a patch release is compatible.
    assert _check(_tree('<Greet who="crew"/>'), {SLAM: examples}, version="0.1.7").passed
    assert not _check(_tree('<Greet who="crew"/>'), {SLAM: examples}, version="0.2.0").passed


def test_an_image_that_declares_nothing_leaves_the_tree_to_the_robot(examples: ImageExports) -> None:
    verdict = _check(_tree('<Greet who="crew"/>', "<Fly/>"), {SLAM: examples, LIDAR: None})
    assert verdict.passed and verdict.undeclared == [LIDAR]


def test_a_label_that_cannot_be_read_names_the_image_and_field() -> None:
    with pytest.raises(ValueError, match=rf"image {SLAM}: label {EXPORTS_LABEL}: field 'coral'"):
        from_labels({EXPORTS_LABEL: '{"schema":1,"component":"a","kind":"skillset","ros":"jazzy"}'}, SLAM)
    assert from_labels({"other": "x"}, SLAM) is None


# --- whole system passes ------------------------------------------------------------------------


def _robot(name: str, model: str) -> RobotNode:
    return RobotNode(
        node_name=name,
        robot=name,
        labels={"coral.dev/robot": name, "fleet": "a", "coral.dev/model": model},
        ready=True,
    )


FLEET = [_robot(f"r{i}", model) for i, model in enumerate(["rover", "rover", "arm", "spot"])]


def _spec(tree: str, **extra: Any) -> dict[str, Any]:
    spec = copy.deepcopy(BASE_SPEC)
    spec["tree"] = {"inline": tree}
    spec["drivers"] = [{"name": "lidar", "image": LIDAR}]
    spec["skillsets"] = [{"name": "slam", "image": SLAM}]
    return {**spec, **extra}


def _pass(spec: dict[str, Any], table: ImageTable, robots: list[RobotNode] = FLEET) -> system_pass.SystemPlan:
    return plan_pass(spec, robots, images=table)


def _declares(component: str, *ids: str, version: str = "0.1.0") -> ImageExports:
    return ImageExports(
        component, "skillset", version, "jazzy", behaviors=tuple(DeclaredBehavior(i, "action") for i in ids)
    )


def test_a_good_change_creates_every_robots_instance(examples: ImageExports) -> None:
    plan = _pass(_spec(_tree('<Greet who="crew"/>')), ImageTable({SLAM: examples, LIDAR: _declares("lidar")}))
    assert plan.problem is None and plan.preflight_notes == []
    assert len(plan.changes.create) == len(FLEET)


@pytest.mark.parametrize(
    ("leaf", "version", "expected"),
    [
        (
            "<Fly/>",
            "0.1.0",
            "tree:4: behavior Fly is exported by none of the images",
        ),
        (
            '<Greet who="crew" volume="3"/>',
            "0.1.0",
            f"port [volume] of Greet is not declared by image {SLAM}",
        ),
        ('<Greet who="crew"/>', "1.0.0", f"image {LIDAR} was built for Coral 1.0.0"),
    ],
    ids=["unknown behavior", "undeclared port", "other Coral major"],
)
def test_a_refused_tree_stalls_the_system_and_creates_nothing(
    examples: ImageExports, leaf: str, version: str, expected: str
) -> None:
    plan = _pass(_spec(_tree(leaf)), ImageTable({SLAM: examples, LIDAR: _declares("lidar", version=version)}))
    assert plan.problem is not None and plan.problem.reason == Reason.PREFLIGHT_FAILED
    assert expected in plan.problem.message and "no robot moves" in plan.problem.message
    assert plan.changes.create == [] and plan.rollout is None and plan.config_maps == []


def test_an_override_is_checked_against_the_images_its_robots_run(examples: ImageExports) -> None:
    """The arm model runs another skillset image, whose behaviors its tree override must use."""
    arm_tree = _tree("<Grip/>")
    override = {
        "name": "arm",
        "robots": {"matchLabels": {"coral.dev/model": "arm"}},
        "images": {"slam": ARM},
        "tree": {"inline": arm_tree},
    }
    spec = _spec(_tree('<Greet who="crew"/>'), overrides=[override])
    table = ImageTable({SLAM: examples, LIDAR: _declares("lidar"), ARM: _declares("arm", "Grip")})
    assert _pass(spec, table).problem is None
    wrong = ImageTable({SLAM: examples, LIDAR: _declares("lidar"), ARM: _declares("arm", "Hold")})
    plan = _pass(spec, wrong)
    assert plan.problem is not None and plan.problem.reason == Reason.PREFLIGHT_FAILED
    assert "behavior Grip is exported by none of the images" in plan.problem.message
    assert ARM in plan.problem.message and "(robots r2)" in plan.problem.message


def test_images_that_declare_nothing_or_were_not_read_fall_back_with_a_note(examples: ImageExports) -> None:
    plan = _pass(_spec(_tree("<Fly/>")), ImageTable({SLAM: examples, LIDAR: None}))
    assert plan.problem is None and len(plan.changes.create) == len(FLEET)
    assert plan.preflight_notes == [
        f"image {LIDAR} declares no behaviors (no label); its trees are checked on the robot"
    ]
    plan = _pass(_spec(_tree("<Fly/>")), ImageTable({SLAM: examples}, unread={LIDAR: "registry down"}))
    assert plan.problem is None
    assert plan.preflight_notes == [f"image {LIDAR} could not be read (registry down); not preflighted"]


def test_the_images_read_are_those_the_spec_and_its_overrides_name() -> None:
    override = {
        "name": "arm",
        "robots": {"matchLabels": {"coral.dev/model": "arm"}},
        "images": {"slam": ARM, "executor": "reg.example/exec:2", "lidar": "reg.example/${robot.name}:1"},
    }
    spec = CoralSystemSpec.model_validate(_spec(_tree("<AlwaysSuccess/>"), overrides=[override]))
    assert operator_preflight.images_to_read(spec) == [ARM, LIDAR, SLAM]


def test_a_hundred_robots_of_three_models_on_five_images_pass(examples: ImageExports) -> None:
    robots = [_robot(f"r{i}", f"m{i % 3}") for i in range(100)]
    trees = {f"m{i}": _tree('<Greet who="crew"/>', f"<Skill{i}/>") for i in range(3)}
    overrides = [
        {
            "name": model,
            "robots": {"matchLabels": {"coral.dev/model": model}},
            "images": {"lidar": f"reg.example/l{model}:1"},
            "tree": {"inline": tree},
        }
        for model, tree in trees.items()
    ]
    table = ImageTable(
        {
            SLAM: examples,
            LIDAR: _declares("lidar"),
            **{f"reg.example/lm{i}:1": _declares("l", f"Skill{i}") for i in range(3)},
        }
    )
    plan = _pass(_spec(_tree('<Greet who="crew"/>'), overrides=overrides), table, robots)
    assert plan.problem is None and len(plan.changes.create) == 100


def test_an_installed_component_prints_the_label_its_image_carries() -> None:
    from click.testing import CliRunner
    from coral.local.cli import verify_command

    result = CliRunner().invoke(verify_command, ["coral/slam-skillset:0.1.0", "--print-label"])
    assert result.exit_code == 0, result.output
    declared = from_labels({EXPORTS_LABEL: result.output.strip()}, "slam")
    assert declared is not None and declared.component == "slam"
    assert "ProcessScan" in {b.id for b in declared.behaviors}


def test_the_executors_own_coordination_behaviors_need_no_image(examples: ImageExports) -> None:
    tree = _tree(
        '<TriggerRemote robot="arm" trigger="go"/>', '<WaitForSharedValue key="target" value="{t}"/>'
    )
    assert _check(tree, {SLAM: examples}).passed


def test_without_declarations_read_nothing_is_refused_and_nothing_said() -> None:
    """Preflight off (no registry read), and a robot model that runs no skillset or driver at all."""
    server = {
        "name": "server",
        "robots": {"matchLabels": {"coral.dev/model": "spot"}},
        "remove": ["lidar", "slam"],
    }
    plan = _pass(_spec(_tree("<Fly/>"), overrides=[server]), ImageTable())
    assert plan.problem is None and plan.preflight_notes == [] and len(plan.changes.create) == len(FLEET)


def test_the_operator_reads_only_the_registries_it_is_told_to() -> None:
    from coral_operator import config
    from coral_operator.reconcile.declarations import ImageDeclarations

    settings = config.from_environment({"CORAL_PREFLIGHT_REGISTRIES": "reg.example, 127.0.0.1:5000"})
    assert settings.preflight_registries == {"reg.example", "127.0.0.1:5000"}
    assert config.from_environment({}).preflight_registries == frozenset()
    declarations = ImageDeclarations(registries=settings.preflight_registries)
    assert declarations.wanted(SLAM) and declarations.wanted("127.0.0.1:5000/coral/x:1")
    assert not declarations.wanted("coral/slam-skillset:0.1.0") and not declarations.wanted(
        "other.example/x:1"
    )
    # Nothing is read from a registry not listed: no request, no note.
    assert declarations.read(["other.example/x:1"]) == ImageTable()
    assert ImageDeclarations(registries=frozenset({"*"})).wanted("docker.io/library/x:1")
