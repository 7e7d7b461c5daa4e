"""Bad input to the cluster tooling is refused with an error that names it (no cluster needed)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from coral_testbed.cluster import external, robots
from coral_testbed.devcluster import dev_cluster


def _kubeconfig(path: Path, context: str) -> Path:
    path.write_text(
        yaml.safe_dump(
            {
                "current-context": context,
                "contexts": [{"name": context, "context": {"cluster": "c"}}],
                "clusters": [{"name": "c", "cluster": {"server": "https://10.1.2.3:6443"}}],
            }
        )
    )
    return path


@pytest.mark.parametrize(
    ("context", "allowed", "accepted"),
    [
        ("kind-coral", "", True),
        ("coral-dev", "", True),
        ("prod-eu", "", False),
        ("prod-eu", "staging, prod-eu", True),
        ("kind", "", False),
    ],
)
def test_only_disposable_contexts_are_accepted(context: str, allowed: str, accepted: bool) -> None:
    assert external.is_disposable(context, allowed) is accepted


def test_a_production_context_is_refused_with_its_name_and_server(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(external.ALLOW_ENV, raising=False)
    path = _kubeconfig(tmp_path / "config", "prod-eu")
    with pytest.raises(external.RefusedCluster, match=r"'prod-eu' \(https://10.1.2.3:6443\)"):
        external.check_disposable(path)
    assert external.check_disposable(_kubeconfig(tmp_path / "kind", "kind-coral")) == "kind-coral"


def test_kubeconfig_lists_and_missing_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(external.RefusedCluster, match="exactly one"):
        external.kubeconfig_from_env(f"{tmp_path}/a:{tmp_path}/b")
    with pytest.raises(external.RefusedCluster, match="no such file"):
        external.kubeconfig_from_env(str(tmp_path / "missing"))


@pytest.mark.parametrize("name", ["R1", "robot_1", "-r1", "r" * 64, ""])
def test_invalid_robot_names_are_refused_by_name(name: str) -> None:
    with pytest.raises(ValueError, match=f"robot name {name!r} is invalid"):
        robots.build_robot_node(name)


def test_robot_labels_cannot_override_the_robot_label() -> None:
    node = robots.build_robot_node("r1", {"coral.dev/robot": "other", "coral.dev/model": "spot"})
    assert node["metadata"]["labels"]["coral.dev/robot"] == "r1"
    assert node["metadata"]["labels"]["coral.dev/model"] == "spot"


@pytest.mark.parametrize("up", [["up"], ["local", "up", "--dir", "{tmp}"]], ids=["kind", "local"])
def test_up_refuses_a_label_without_a_value_separator(tmp_path: Path, up: list[str]) -> None:
    command = [part.format(tmp=tmp_path) for part in up]
    result = CliRunner().invoke(dev_cluster, [*command, "--label", "coral.dev/model"])
    assert result.exit_code == 2
    assert "'coral.dev/model' is not KEY=VALUE" in result.output


def test_robot_commands_without_a_running_control_plane_say_how_to_start_one(tmp_path: Path) -> None:
    result = CliRunner().invoke(dev_cluster, ["local", "robots", "add", "r1", "--dir", str(tmp_path)])
    assert result.exit_code == 1
    assert "coral dev-cluster local up" in result.output
