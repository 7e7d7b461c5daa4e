"""Every example passes `coral validate`: compose projects, mission files and the GitOps kustomization.

Regression: the fleet examples named a driver image no component provides and tree nodes
(`IsLidarHealthy`, `EstimatePose`) no component exports, so a user copying them got a system
whose executor waited forever for plugins (issue 14).
"""

from __future__ import annotations

import shutil
import subprocess
from importlib import metadata
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from coral.local.cli import validate_command
from coral_testbed.missions import manifests

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


def _kubectl() -> str:
    found = shutil.which("kubectl")
    if found:
        return found
    from coral_testbed.cluster import binaries

    return str(binaries.find_bin_dir(("kubectl",)) / "kubectl")


def _targets() -> list[Path]:
    projects = [p.parent for p in EXAMPLES.glob("*/compose.yaml")]
    missions = list(EXAMPLES.glob("*/mission.yaml"))
    return sorted({*projects, *missions})


def test_every_example_is_covered() -> None:
    covered = {p if p.is_dir() else p.parent for p in _targets()}
    with_coral_files = {p.parent for p in EXAMPLES.glob("*/README.md")} - {EXAMPLES / "gitops"}
    assert with_coral_files <= covered


@pytest.mark.parametrize("target", _targets(), ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_the_example_passes_coral_validate(target: Path) -> None:
    result = CliRunner().invoke(validate_command, [str(target)])
    assert result.exit_code == 0, result.output


def test_the_gitops_fleet_rendered_by_kustomize_passes_coral_validate() -> None:
    rendered = subprocess.run(
        [_kubectl(), "kustomize", str(EXAMPLES / "gitops" / "fleet")],
        check=True,
        capture_output=True,
        text=True,
        timeout=60,
    ).stdout
    result = CliRunner().invoke(validate_command, ["-"], input=rendered)
    assert result.exit_code == 0, result.output


def test_validate_names_the_system_and_field_of_a_bad_manifest() -> None:
    bad = (EXAMPLES / "fleet" / "mission.yaml").read_text().replace("<Sleep msec", "<NoSuchNode msec")
    bad = bad.replace("coral/slam-skillset:0.1.0", "coral/not-a-component:0.1.0")
    result = CliRunner().invoke(validate_command, ["-"], input=bad)
    assert result.exit_code == 1
    assert "coralsystem/fleet: spec.tree:" in result.output and "NoSuchNode" in result.output
    assert "coralsystem/fleet: spec.skillsets[0] (slam)" in result.output


@pytest.mark.parametrize(("robot", "model"), sorted(manifests.SITE_ROBOTS.items()))
def test_each_robot_model_of_the_site_runs_a_tree_its_own_images_export(robot: str, model: str) -> None:
    """`coral validate` checks the system's own tree; each robot's effective tree, with the labels
    `coral demo` gives its Node, is checked here against the images it runs, as preflight does."""
    from coral.local import checking
    from coral_core import bt, image_exports, preflight
    from coral_operator.api.system import CoralSystemSpec
    from coral_operator.planning import selection
    from coral_operator.planning.observed import RobotNode
    from coral_operator.planning.overrides import BaseConfig, EffectiveConfig, effective_config

    spec = CoralSystemSpec.model_validate(yaml.safe_load(manifests.SITE_MISSION.read_text())["spec"])
    key, value = manifests.SITE_LABEL.split("=")
    labels = {"coral.dev/robot": robot, "coral.dev/model": model, key: value}
    assert selection.matches(spec.robots, labels)
    base = BaseConfig.of_spec(spec, spec.tree.inline or "", spec.parameters.inline or "")
    config = effective_config(base, spec.overrides, RobotNode(robot, robot, labels, True))
    assert isinstance(config, EffectiveConfig), config
    assert len(config.applied) == (0 if model == "server" else 1), config.applied
    declared: dict[str, image_exports.ImageExports | None] = {}
    for component in [*config.drivers, *config.skillsets]:
        verification = checking.verify_component(component.image)
        assert verification.manifest is not None, verification.problems
        declared[component.image] = verification.manifest.image_exports()
    document = bt.load_tree_text(config.tree, filename=f"{robot} tree", main_tree=config.main_tree_id)
    verdict = preflight.check_document(document, declared, metadata.version("coral-on-kubernetes"))
    assert verdict.problems == [] and verdict.undeclared == [], verdict
