"""How a compose service becomes a local command: x-coral command, entry points by image name, executors."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from coral.local import components
from coral_core.compose import Project, Service


@pytest.mark.parametrize(
    ("image", "repository"),
    [
        ("coral/slam-skillset:0.1.0", "coral/slam-skillset"),
        ("ghcr.io/acme/slam-skillset:1.2", "acme/slam-skillset"),
        ("localhost:5000/slam@sha256:abc", "slam"),
        ("slam", "slam"),
    ],
)
def test_image_names_lose_registry_tag_and_digest(image: str, repository: str) -> None:
    assert components.image_repository(image) == repository


def _project(tmp_path: Path) -> Project:
    return Project(
        name="p",
        file=tmp_path / "compose.yaml",
        services=[],
        tree=tmp_path / "tree.xml",
        params=tmp_path / "params.yaml",
    )


def _paths(tmp_path: Path) -> components.Paths:
    return components.Paths(
        plugins=tmp_path / "plugins", output=tmp_path / "out", status_jsonl=tmp_path / "s.jsonl"
    )


def test_a_skillset_image_runs_its_component_through_the_sdk(tmp_path: Path) -> None:
    service = Service(
        name="slam", role="skillset", line=1, image="registry.example.com/coral/slam-skillset:2"
    )
    argv = components.command_for(_project(tmp_path), service, _paths(tmp_path))
    assert argv[:4] == [sys.executable, "-m", "coral.sdk.run", "coral_skillsets.slam.skillset:SlamSkillset"]
    assert argv[4:] == [
        "--plugins",
        str(tmp_path / "plugins"),
        "--name",
        "slam",
        "--params",
        str(tmp_path / "params.yaml"),
    ]


def test_an_installed_entry_point_is_found_by_the_last_part_of_the_image_name() -> None:
    known = {"acme/lidar-driver": "acme_lidar.driver:Lidar"}
    service = Service(name="lidar", role="driver", line=1, image="docker.io/other/lidar-driver:1")
    assert components.component_target(service, known) == "acme_lidar.driver:Lidar"


def test_an_unknown_image_says_what_was_looked_up() -> None:
    service = Service(name="x", role="skillset", line=1, image="acme/unknown:1")
    with pytest.raises(components.ComponentNotFound, match="no installed component named 'acme/unknown'"):
        components.component_target(service, {})


def test_an_x_coral_command_has_its_placeholders_filled(tmp_path: Path) -> None:
    service = Service(
        name="d", role="driver", line=1, command=["{python}", "tool.py", "{plugins}", "{name}", "{output}"]
    )
    argv = components.command_for(_project(tmp_path), service, _paths(tmp_path))
    assert argv == [sys.executable, "tool.py", str(tmp_path / "plugins"), "d", str(tmp_path / "out")]


def test_an_executor_gets_the_tree_parameters_status_file_and_rate(tmp_path: Path) -> None:
    service = Service(name="executor", role="executor", line=1, rate=20.0, main_tree="Main")
    argv = components.command_for(_project(tmp_path), service, _paths(tmp_path))
    assert argv[:3] == [sys.executable, "-m", "coral.executor"]
    flags = dict(zip(argv[3::2], argv[4::2], strict=True))
    assert flags == {
        "--tree": str(tmp_path / "tree.xml"),
        "--plugins": str(tmp_path / "plugins"),
        "--status-jsonl": str(tmp_path / "s.jsonl"),
        "--name": "executor",
        "--params": str(tmp_path / "params.yaml"),
        "--main-tree": "Main",
        "--rate": "20",
    }


def test_executors_get_their_own_groot2_port_pairs_when_coral_run_asks(tmp_path: Path) -> None:
    project = _project(tmp_path)
    project.services = [
        Service(name="first", role="executor", line=1),
        Service(name="second", role="executor", line=2),
    ]
    project.groot2_port, project.groot2_allow_hooks, project.groot2_wait_s = 1667, True, 30.0
    first, second = (components.command_for(project, s, _paths(tmp_path)) for s in project.services)
    assert first[first.index("--groot2-port") + 1] == "1667"
    assert second[second.index("--groot2-port") + 1] == "1669"
    assert "--groot2-allow-hooks" in first and first[first.index("--groot2-wait") + 1] == "30"


def test_executors_publish_nothing_over_groot2_unless_asked(tmp_path: Path) -> None:
    service = Service(name="executor", role="executor", line=1)
    argv = components.command_for(_project(tmp_path), service, _paths(tmp_path))
    assert not any(arg.startswith("--groot2") for arg in argv)
