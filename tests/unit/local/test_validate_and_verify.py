"""`coral validate`, `coral verify` and `coral nodes-model` on the SLAM example and broken copies of it."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner
from coral_core.command import main


def _line_of(path: Path, text: str) -> int:
    return next(n for n, line in enumerate(path.read_text().splitlines(), start=1) if text in line)


def test_the_example_is_valid(project: Path) -> None:
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 0, result.output
    assert "valid" in result.output


def test_a_misspelled_node_name_is_reported_with_file_and_line(project: Path) -> None:
    tree = project / "tree.xml"
    tree.write_text(tree.read_text().replace("<ProcessScan ", "<ProcesScan "))
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 1
    line = _line_of(tree, "<ProcesScan ")
    assert f"{tree}:{line}" in result.output and "ProcesScan" in result.output


def test_a_broken_parameters_file_and_compose_file_are_reported_with_lines(project: Path) -> None:
    params = project / "params.yaml"
    params.write_text(params.read_text().replace("slam:\n  ros__parameters:", "slam:\n  parameters:"))
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 1 and f"{params}:" in result.output

    compose = project / "compose.yaml"
    compose.write_text(compose.read_text().replace("profiles: [skillsets]", "profiles: [skilsets]", 1))
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 1
    assert (
        f"{compose}:{_line_of(compose, 'profiles: [skilsets]')}: service slam needs exactly one"
        in result.output
    )


def test_verify_accepts_the_reference_components_by_image_name() -> None:
    result = CliRunner().invoke(main, ["verify", "coral/slam-skillset:0.1.0"])
    assert result.exit_code == 0, result.output
    assert "valid skillset 'slam'" in result.output and "ProcessScan" in result.output


def test_verify_refuses_what_is_not_a_component() -> None:
    result = CliRunner().invoke(main, ["verify", "coral_skillsets.slam.core:SlamCore"])
    assert result.exit_code == 1 and "not a Coral component" in result.output
    result = CliRunner().invoke(main, ["verify", "acme/nothing:1"])
    assert result.exit_code == 1 and "no installed component named 'acme/nothing'" in result.output


def test_nodes_model_lists_every_behavior_of_the_project_for_groot(project: Path) -> None:
    result = CliRunner().invoke(main, ["nodes-model", str(project)])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    # BT.CPP's layout: 4-space indentation, empty nodes closed as `<X/>`, C++ type names.
    assert lines[:3] == [
        '<root BTCPP_format="4">',
        "    <TreeNodesModel>",
        '        <Action ID="DisableLocalization"/>',
    ]
    for node_id in ("ProcessScan", "SaveMap", "IsDataExhausted", "TakeSnapshot"):
        assert f'ID="{node_id}"' in result.output
    assert (
        '            <input_port name="topic" type="std::string" default="/slam/stop">std_msgs/Empty topic'
        "</input_port>" in lines
    )
    assert 'type="string"' not in result.output


def test_a_tree_saved_by_groot_with_the_palette_in_it_still_validates(project: Path) -> None:
    """Groot2 writes the palette it loaded into the tree file it saves: `coral validate` accepts it."""
    palette = CliRunner().invoke(main, ["nodes-model", str(project)])
    assert palette.exit_code == 0, palette.output
    tree = project / "tree.xml"
    model = palette.output.split('<root BTCPP_format="4">', 1)[1].rsplit("</root>", 1)[0]
    tree.write_text(tree.read_text().replace("</root>", model + "</root>"))
    assert "<TreeNodesModel>" in tree.read_text()
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 0, result.output
    # The palette in the file does not override the manifests: a port they lack is still an error.
    tree.write_text(tree.read_text().replace("<IsStopRequested topic=", "<IsStopRequested topc="))
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 1 and f"{tree}:{_line_of(tree, 'topc=')}" in result.output


def test_an_unset_required_variable_is_a_warning_for_validation(
    project: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("CORAL_BAG")
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 0, result.output
    assert (
        f"warning: {project / 'compose.yaml'}:" in result.output and "CORAL_BAG is not set" in result.output
    )
