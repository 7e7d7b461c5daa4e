"""Every example passes `coral validate`: compose projects, mission files and the GitOps kustomization.

Regression: the fleet examples named a driver image no component provides and tree nodes
(`IsLidarHealthy`, `EstimatePose`) no component exports, so a user copying them got a system
whose executor waited forever for plugins (issue 14).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner
from coral.local.cli import validate_command

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
