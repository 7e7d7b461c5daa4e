"""Project files a user got wrong in ways that used to end in a traceback or outside the run's
folder: a file that is not UTF-8, YAML nested past what the parser can follow, a run handle that is a
path. `coral validate`, `coral run` (which parses the same way) and `coral convert` name the file and
line, or the option, instead."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner
from coral_core.command import main
from coral_operator.convert.cli import convert_command
from coral_operator.planning import validation

# A degree sign saved by an editor set to Latin-1, on the file's third line.
LATIN1 = "# a comment\n# another\n# angle in \u00b0\n".encode("latin-1")
DEEP = "a: " + "[" * 5000 + "\n"


def _spoil(path: Path) -> None:
    path.write_bytes(LATIN1 + path.read_bytes())


def _validate(project: Path) -> str:
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 1, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output
    return result.output


@pytest.mark.parametrize("name", ["compose.yaml", "params.yaml", ".env"])
def test_a_byte_that_is_not_utf8_is_named_with_its_file_and_line(project: Path, name: str) -> None:
    path = project / name
    if name == ".env":
        path.write_text("SPEED=1\n")
    _spoil(path)
    assert f"{path}:3: not UTF-8 text (byte 0xb0)" in _validate(project)


def test_a_tree_and_a_file_it_includes_are_read_as_utf8_with_the_line(project: Path) -> None:
    tree = project / "tree.xml"
    original = tree.read_text()
    tree.write_bytes(b"<!-- ok -->\n<!-- \xe9 -->\n" + original.encode())
    assert f"{tree}:2: not UTF-8 text (byte 0xe9)" in _validate(project)

    included = project / "steps.xml"
    included.write_bytes(b'<root BTCPP_format="4">\n\xff\n</root>\n')
    root_tag = '<root BTCPP_format="4" main_tree_to_execute="Main">'
    assert root_tag in original
    tree.write_text(original.replace(root_tag, root_tag + '<include path="steps.xml"/>', 1))
    assert f"{included}:2: not UTF-8 text (byte 0xff)" in _validate(project)


@pytest.mark.parametrize("name", ["compose.yaml", "params.yaml"])
def test_yaml_nested_past_the_parser_is_a_problem_not_a_crash(project: Path, name: str) -> None:
    path = project / name
    path.write_text(DEEP)
    assert f"{path}: invalid YAML: the document nests too deeply to be read" in _validate(project)


def test_mission_manifests_that_are_not_utf8_are_named(tmp_path: Path) -> None:
    mission = tmp_path / "mission.yaml"
    mission.write_bytes(b"apiVersion: coral.dev/v1alpha1\nkind: CoralSystem\nmetadata: {name: \xff}\n")
    for arguments, stdin, where in (
        ([str(mission)], None, f"{mission}:3"),
        (["-"], mission.read_bytes(), "<stdin>:3"),
    ):
        result = CliRunner().invoke(main, ["validate", *arguments], input=stdin)
        assert result.exit_code == 1, result.output
        assert f"{where}: not UTF-8 text (byte 0xff)" in result.output


def test_convert_names_a_tree_that_is_not_utf8(project: Path) -> None:
    _spoil(project / "tree.xml")
    result = CliRunner().invoke(convert_command, [str(project)])
    assert result.exit_code != 0
    assert f"{project / 'tree.xml'}:3: not UTF-8 text (byte 0xb0)" in result.output


def test_the_operator_words_deep_parameters_as_a_yaml_problem() -> None:
    assert validation.validate_parameters(DEEP, "params.yaml") == [
        "params.yaml:1: invalid YAML: the document nests too deeply to be read"
    ]


def test_a_run_handle_that_is_a_path_is_refused(project: Path) -> None:
    result = CliRunner().invoke(main, ["run", "--handle", "../../elsewhere", str(project)])
    assert result.exit_code == 2
    assert "'../../elsewhere': use letters, digits" in result.output
