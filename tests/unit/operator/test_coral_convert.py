"""`coral convert DIR` turns Coral's three files into a CoralSystem the operator accepts."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from coral_operator.api.system import CoralSystemSpec
from coral_operator.convert.cli import convert_command
from operator_specs import TREE

ROOT = Path(__file__).resolve().parents[3]

COMPOSE = """services:
  lidar:
    image: example/lidar:1
    profiles: [drivers]
    privileged: true
    devices: ["/dev/ttyUSB0:/dev/ttyUSB0"]
    environment:
      ROS_DOMAIN_ID: "7"
      FRAME: laser
  slam:
    image: example/slam:1
    profiles: [skillsets]
    command: python -m slam
    healthcheck:
      test: ["CMD", "test", "-f", "/ready"]
  executor:
    image: example/executor:1
    profiles: [executors]
    volumes: ["plugins:/plugins"]
"""


def _folder(tmp_path: Path, compose: str = COMPOSE) -> Path:
    (tmp_path / "compose.yaml").write_text(compose)
    (tmp_path / "tree.xml").write_text(TREE)
    (tmp_path / "params.yaml").write_text("slam:\n  ros__parameters:\n    voxel: 0.5\n")
    return tmp_path


def test_the_three_files_become_a_valid_coral_system(tmp_path: Path) -> None:
    result = CliRunner().invoke(
        convert_command, [str(_folder(tmp_path)), "--name", "demo", "--robots", "fleet=a"]
    )
    assert result.exit_code == 0, result.output
    manifest = yaml.safe_load(result.stdout)
    assert manifest["kind"] == "CoralSystem" and manifest["metadata"]["name"] == "demo"
    spec = CoralSystemSpec.model_validate(manifest["spec"])
    assert spec.robots.match_labels == {"fleet": "a"}
    assert spec.ros.domain_id == 7
    assert spec.drivers[0].privileged and spec.drivers[0].devices[0].host_path == "/dev/ttyUSB0"
    assert spec.skillsets[0].args == ["python", "-m", "slam"]
    assert spec.skillsets[0].readiness is not None and spec.skillsets[0].readiness.exec == [
        "test",
        "-f",
        "/ready",
    ]
    assert spec.tree.inline == TREE
    assert "not a host bind mount" in result.stderr


def test_a_service_without_a_coral_profile_is_named(tmp_path: Path) -> None:
    compose = "services:\n  tool:\n    image: x\n"
    result = CliRunner().invoke(convert_command, [str(_folder(tmp_path, compose))])
    assert result.exit_code != 0
    assert "compose.yaml:2" in result.output and "needs exactly one of the profiles" in result.output


def test_the_compose_project_sets_startup_and_transient_drivers(tmp_path: Path) -> None:
    compose = COMPOSE.replace(
        "    privileged: true\n", "    privileged: true\n    x-coral:\n      transient: true\n"
    )
    compose = "x-coral:\n  ready_timeout_s: 30\n  on_timeout: proceed\n  rate: 20\n" + compose
    result = CliRunner().invoke(convert_command, [str(_folder(tmp_path, compose))])
    assert result.exit_code == 0, result.output
    spec = CoralSystemSpec.model_validate(yaml.safe_load(result.stdout)["spec"])
    assert spec.drivers[0].transient
    assert (spec.startup.health_timeout_seconds, spec.startup.on_timeout) == (30, "Proceed")
    assert spec.tree.tick_rate_hz == 20
    assert spec.robots.match_labels == {"coral.dev/robot": "robot-1"}


def test_a_broken_tree_is_refused_with_its_line(tmp_path: Path) -> None:
    folder = _folder(tmp_path)
    (folder / "tree.xml").write_text("<root>\n<BehaviorTree ID='a'>\n</root>\n")
    result = CliRunner().invoke(convert_command, [str(folder)])
    assert result.exit_code != 0 and "tree.xml:3:" in result.output


@pytest.mark.parametrize(
    ("example", "arguments", "environment"),
    [
        ("fleet", ["--name", "fleet", "--robots", "fleet=demo"], {}),
        ("lidar-slam", [], {"CORAL_BAG": "/var/lib/coral/bags/lidar-slam"}),
    ],
)
def test_the_examples_missions_are_the_output_of_convert(
    example: str, arguments: list[str], environment: dict[str, str]
) -> None:
    folder = ROOT / "examples" / example
    result = CliRunner().invoke(convert_command, [str(folder), *arguments], env=environment)
    assert result.exit_code == 0, result.output
    committed = (folder / "mission.yaml").read_text()
    assert yaml.safe_load(committed) == yaml.safe_load(result.stdout)


def test_included_files_beside_the_tree_travel_in_the_system(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "x-coral:\n  tree: tree.xml\n" + COMPOSE)
    nav = (
        '<root BTCPP_format="4">\n  <BehaviorTree ID="Nav">\n    <AlwaysSuccess/>\n'
        "  </BehaviorTree>\n</root>\n"
    )
    (folder / "nav.xml").write_text(nav)
    tree = (
        '<root BTCPP_format="4" main_tree_to_execute="Main">\n  <include path="nav.xml"/>\n'
        '  <BehaviorTree ID="Main">\n    <SubTree ID="Nav"/>\n  </BehaviorTree>\n</root>\n'
    )
    (folder / "tree.xml").write_text(tree)
    result = CliRunner().invoke(convert_command, [str(folder), "--robots", "fleet=a"])
    assert result.exit_code == 0, result.output
    spec = CoralSystemSpec.model_validate(yaml.safe_load(result.stdout)["spec"])
    assert spec.tree.files == {"nav.xml": nav}


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--namespace", "Field_Trials"], "'Field_Trials' is not a namespace name"),
        (["--robots", "fleet zone=a"], "--robots 'fleet zone=a': 'fleet zone' is not a Kubernetes label key"),
        (
            ["--robots", "zone=north east"],
            "--robots 'zone=north east': 'north east' is not a Kubernetes label value",
        ),
    ],
)
def test_a_namespace_or_robot_label_kubernetes_refuses_is_named_before_conversion(
    tmp_path: Path, arguments: list[str], message: str
) -> None:
    result = CliRunner().invoke(convert_command, [str(_folder(tmp_path)), *arguments])
    assert result.exit_code == 2
    assert message in result.output and "errors.pydantic.dev" not in result.output


# Issue 52: convert read image, command and volumes from the file before interpolation, so a
# mission converted from a compose file with `${VARIABLES}` ran other images and mounts than
# `coral run` of the same folder. Every case sets one variable in the environment and one in `.env`.
INTERPOLATED = """services:
  lidar:
    image: ${REGISTRY}/lidar:${TAG:-1}
    profiles: [drivers]
    entrypoint: ${PYTHON} -m lidar
    command: ["--port", "${PORT}"]
    privileged: ${PRIVILEGED}
    devices: ["${DEVICE}:/dev/lidar"]
    volumes: ["${BAGS}:/bags:ro", "$${NOT_A_VARIABLE}:/x"]
    environment:
      FRAME: ${FRAME}
  executor:
    image: ${REGISTRY}/executor:1
    profiles: [executors]
"""
ENVIRONMENT = {"REGISTRY": "registry.site", "PYTHON": "python3", "PRIVILEGED": "true", "FRAME": "laser"}
DOTENV = "PORT=7000\nDEVICE=/dev/ttyUSB0\nBAGS=/var/lib/coral/bags\nTAG=2\n"


def _converted_interpolated(tmp_path: Path) -> CoralSystemSpec:
    folder = _folder(tmp_path, INTERPOLATED)
    (folder / ".env").write_text(DOTENV)
    result = CliRunner().invoke(convert_command, [str(folder)], env=ENVIRONMENT)
    assert result.exit_code == 0, result.output
    return CoralSystemSpec.model_validate(yaml.safe_load(result.stdout)["spec"])


def test_images_are_interpolated_as_coral_run_reads_them(tmp_path: Path) -> None:
    from coral_core.compose import parse_compose

    spec = _converted_interpolated(tmp_path)
    converted = [spec.drivers[0].image, spec.executors[0].image]
    assert converted == ["registry.site/lidar:2", "registry.site/executor:1"]
    ran = parse_compose(tmp_path / "compose.yaml", {**ENVIRONMENT})
    assert [service.image for service in ran.services] == converted


def test_entrypoint_and_command_are_interpolated(tmp_path: Path) -> None:
    driver = _converted_interpolated(tmp_path).drivers[0]
    assert driver.command == ["python3", "-m", "lidar"]
    assert driver.args == ["--port", "7000"]


def test_volumes_and_devices_are_interpolated_and_dollar_dollar_stays_a_dollar(tmp_path: Path) -> None:
    folder = _folder(tmp_path, INTERPOLATED)
    (folder / ".env").write_text(DOTENV)
    result = CliRunner().invoke(convert_command, [str(folder)], env=ENVIRONMENT)
    assert result.exit_code == 0, result.output
    driver = CoralSystemSpec.model_validate(yaml.safe_load(result.stdout)["spec"]).drivers[0]
    assert [(m.host_path, m.mount_path, m.read_only) for m in driver.host_paths] == [
        ("/var/lib/coral/bags", "/bags", True)
    ]
    assert "${NOT_A_VARIABLE}:/x is not a host bind mount" in result.stderr
    assert [(d.host_path, d.container_path) for d in driver.devices] == [("/dev/ttyUSB0", "/dev/lidar")]


def test_an_interpolated_boolean_and_environment_are_typed_as_compose_casts_them(tmp_path: Path) -> None:
    driver = _converted_interpolated(tmp_path).drivers[0]
    assert driver.privileged is True
    assert [(e.name, e.value) for e in driver.env] == [("FRAME", "laser")]


def test_a_required_variable_in_a_volume_is_named_with_its_line(tmp_path: Path) -> None:
    compose = COMPOSE.replace('["plugins:/plugins"]', '["${MAPS:?set MAPS to the maps folder}:/maps"]')
    result = CliRunner().invoke(convert_command, [str(_folder(tmp_path, compose))], env={"MAPS": None})
    assert result.exit_code != 0
    assert "compose.yaml:19: variable MAPS is required: set MAPS to the maps folder" in result.output


def test_a_volume_that_is_neither_a_string_nor_a_mapping_is_named(tmp_path: Path) -> None:
    compose = COMPOSE.replace('["plugins:/plugins"]', "[[/srv/maps, /maps]]")
    result = CliRunner().invoke(convert_command, [str(_folder(tmp_path, compose))])
    assert result.exit_code == 1
    assert "services.executor.volumes: expected a list of strings or mappings" in result.output
