"""The `coral plugins`, `coral skillset` and `coral executor` command lines, and their bad-input paths."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from coral.plugins import exporting
from coral.plugins import manifest as manifests
from coral.sdk import running
from coral_core.command import main
from coral_skillsets.examples import behaviors
from coral_skillsets.examples.skillset import ExampleSkillset

from .plugin_builders import greeter_plugin


def _export_examples(plugins: Path) -> None:
    ref = manifests.ComponentRef(name="examples", kind="skillset", node_name="examples")
    exporting.export_plugin(plugins, ref, [behaviors.Greet, behaviors.Count, behaviors.IsAtLeast])


def test_plugins_list_shows_loadable_refused_and_clashing_plugins(tmp_path: Path) -> None:
    _export_examples(tmp_path)
    greeter_plugin(tmp_path, "other", "Greet", "hi")
    (tmp_path / "junk").mkdir()
    result = CliRunner().invoke(main, ["plugins", "list", str(tmp_path)])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0] == "examples (skillset, not ready): Greet, Count, IsAtLeast"
    assert lines[1] == "other (skillset, not ready): Greet"
    assert lines[2].startswith("plugin junk refused: ")
    assert (
        lines[3]
        == "node ID Greet is exported by both examples and other; using examples (first by component name)"
    )


def test_plugins_model_prints_a_groot_palette(tmp_path: Path) -> None:
    _export_examples(tmp_path)
    result = CliRunner().invoke(main, ["plugins", "model", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert '<Condition ID="IsAtLeast">' in result.output
    assert (
        '<input_port name="who" type="std::string" default="world">Who to greet</input_port>' in result.output
    )


def test_skillset_verb_rejects_a_target_without_a_class() -> None:
    result = CliRunner().invoke(main, ["skillset", "coral_skillsets.examples.skillset"])
    assert result.exit_code == 2
    assert "must be written MODULE:CLASS" in result.output


def test_a_bad_parameters_file_stops_a_component_before_ros_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    params = tmp_path / "params.yaml"
    params.write_text("examples:\n  ros__parameters:\n    work_delay_s: [1, {a: 2}]\n")
    code = running.run_component(ExampleSkillset, plugins_dir=tmp_path / "plugins", params_file=params)
    assert code == running.EXIT_BAD_INPUT
    assert f"{params}:3: parameter 'work_delay_s' arrays may hold scalars only" in capsys.readouterr().err
    assert not (tmp_path / "plugins").exists()


def test_the_executor_exits_2_naming_file_and_line_for_a_malformed_tree(tmp_path: Path) -> None:
    tree = tmp_path / "tree.xml"
    tree.write_text('<root BTCPP_format="4">\n  <BehaviorTree ID="Main">\n    <Sequence>\n</root>\n')
    status = tmp_path / "status.jsonl"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "coral.executor",
            "--tree",
            str(tree),
            "--plugins",
            str(tmp_path),
            "--status-jsonl",
            str(status),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert f"{tree}:" in status.read_text()
    assert '"exit_code": 2' in status.read_text()


def test_export_only_writes_a_loadable_plugin_without_ros(tmp_path: Path) -> None:
    plugins = tmp_path / "plugins"
    result = CliRunner().invoke(
        main,
        [
            "skillset",
            "coral_skillsets.examples.skillset:ExampleSkillset",
            "--plugins",
            str(plugins),
            "--export-only",
        ],
    )
    assert result.exit_code == 0, result.output
    manifest = manifests.read_manifest(plugins / "examples")
    assert [b.id for b in manifest.behaviors] == ["Greet", "Count", "IsAtLeast", "WaitForCount"]
    assert not (plugins / "examples" / "ready").exists(), "an image-baked export is not a running component"
    assert (
        CliRunner()
        .invoke(main, ["skillset", "coral_skillsets.examples.skillset:ExampleSkillset", "--export-only"])
        .exit_code
        == 2
    )
