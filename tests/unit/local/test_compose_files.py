"""Compose files as Coral reads them: roles from profiles, x-coral fields, interpolation, file:line errors."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral_core.compose import ComposeError, find_compose_file, interpolate, parse_compose

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "lidar-slam"


def _project(tmp_path: Path, text: str, **files: str) -> Path:
    (tmp_path / "compose.yaml").write_text(text)
    (tmp_path / "tree.xml").write_text("<root BTCPP_format='4'/>")
    for name, content in files.items():
        (tmp_path / name).write_text(content)
    return tmp_path / "compose.yaml"


def test_the_example_parses_into_drivers_skillsets_and_executors() -> None:
    project = parse_compose(find_compose_file(EXAMPLE), {"CORAL_BAG": "/bags/x"})
    roles = {s.name: s.role for s in project.services}
    assert roles == {
        "bag_player": "driver",
        "slam": "skillset",
        "snapshot": "skillset",
        "executor": "executor",
    }
    player = project.by_role("driver")[0]
    assert player.transient and player.environment == {"CORAL_BAG": "/bags/x"}
    assert player.image == "coral/bag-player:0.1.0"
    assert project.tree == EXAMPLE / "tree.xml" and project.params == EXAMPLE / "params.yaml"
    assert project.by_role("executor")[0].rate == 20


def test_a_required_variable_that_is_unset_is_reported_with_its_line() -> None:
    with pytest.raises(ComposeError, match=r"compose.yaml:18: variable CORAL_BAG is required: set CORAL_BAG"):
        parse_compose(find_compose_file(EXAMPLE), {})


# The cases of the compose specification's interpolation.md and Docker Compose's documentation.
@pytest.mark.parametrize(
    ("text", "env", "expected"),
    [
        ("${A}", {"A": "1"}, "1"),
        ("$A", {"A": "1"}, "1"),
        ("${MISSING}", {}, ""),
        ("${A:-x}", {"A": ""}, "x"),
        ("${A:-x}", {}, "x"),
        ("${A:-x}", {"A": "1"}, "1"),
        ("${A-x}", {"A": ""}, ""),
        ("${A-x}", {}, "x"),
        ("${A:+alt}", {"A": "1"}, "alt"),
        ("${A:+alt}", {"A": ""}, ""),
        ("${A:+alt}", {}, ""),
        ("${A+alt}", {"A": ""}, "alt"),
        ("${A+alt}", {}, ""),
        ("${A?err}", {"A": ""}, ""),
        ("$A/$$B", {"A": "a"}, "a/$B"),
        ("$$", {}, "$"),
        ("$${A}", {"A": "1"}, "${A}"),
        ("${A:-${B}}", {"B": "b"}, "b"),
        ("${A:-${B:-default}}", {}, "default"),
        ("${A:-x}y${B}", {"B": "z"}, "xyz"),
        ("${A:-a b}", {}, "a b"),
        ("pre-$A-post", {"A": "1"}, "pre-1-post"),
        ("${A:-{x}}", {}, "{x}"),
    ],
)
def test_variables_are_interpolated_as_compose_does(text: str, env: dict[str, str], expected: str) -> None:
    assert interpolate(text, env, Path("f"), 1) == expected


@pytest.mark.parametrize(
    ("text", "env", "message"),
    [
        ("${A:?set A first}", {}, "variable A is required: set A first"),
        ("${A:?set A first}", {"A": ""}, "variable A is required: set A first"),
        ("${A?}", {}, "variable A is required: not set"),
        ("${A:?}", {"A": ""}, "variable A is required: empty"),
        ("${A:?need $B}", {"B": "bee"}, "variable A is required: need bee"),
    ],
)
def test_a_required_variable_that_is_missing_is_an_error_with_the_message(
    text: str, env: dict[str, str], message: str
) -> None:
    with pytest.raises(ComposeError, match=f"^f:3: {message}$"):
        interpolate(text, env, Path("f"), 3)


@pytest.mark.parametrize("text", ["${A", "${}", "${A B}", "${-x}", "$5", "cost: 5$", "${A:x}"])
def test_an_invalid_interpolation_is_refused_with_its_line(text: str) -> None:
    with pytest.raises(ComposeError, match="^f:7: invalid interpolation format"):
        interpolate(text, {"A": "1"}, Path("f"), 7)


def test_dotenv_values_are_parsed_by_dotenv_rules_and_interpolated(tmp_path: Path) -> None:
    file = _project(
        tmp_path,
        "services:\n  d:\n    image: x\n    profiles: [drivers]\n"
        "    environment: [A=$A, B=$B, C=$C, D=$D, E=$E]\n",
        **{
            ".env": "# comment\nexport A='single $quoted'\nB=\"${FROM_ENV}/x\"  # trailing\n"
            'C=${A}-c\nD="two\nlines"\nE=${FROM_ENV:-unused}\n'
        },
    )
    service = parse_compose(file, {"FROM_ENV": "env", "E": "from the environment"}).services[0]
    assert service.environment == {
        "A": "single $quoted",
        "B": "env/x",
        "C": "single $quoted-c",
        "D": "two\nlines",
        "E": "from the environment",
    }


@pytest.mark.parametrize(
    ("compose", "dotenv", "message"),
    [
        pytest.param("services: {}\n", "A=1\nB='unclosed\n", r"\.env:2: cannot parse", id="bad .env line"),
        pytest.param(
            "services:\n  a:\n    image: x\n    profiles: [tools]\n",
            None,
            r"compose.yaml:4: service a needs exactly one of the profiles",
            id="no Coral profile",
        ),
        pytest.param(
            "services:\n  a:\n    image: x\n    profiles: [drivers]\n    x-coral:\n"
            "      transient: true\n      restart: always\n",
            None,
            r"compose.yaml:7: unknown x-coral option 'restart' in service a",
            id="unknown x-coral option",
        ),
        pytest.param(
            "services:\n  s:\n    image: x\n    profiles: [skillsets]\n    x-coral:\n      transient: true\n",
            None,
            r"compose.yaml:6: only drivers can be transient",
            id="transient skillset",
        ),
        pytest.param(
            "services:\n  a:\n    image: [x\n", None, r"compose.yaml:4: invalid YAML", id="invalid YAML"
        ),
        pytest.param(
            "name: ../../elsewhere\nservices: {}\n",
            None,
            r"compose.yaml:1: name '../../elsewhere' must hold only lowercase letters",
            id="project name that is a path",
        ),
        pytest.param(
            "name: Mission\nservices: {}\n", None, r"compose.yaml:1: name 'Mission'", id="uppercase name"
        ),
        pytest.param(
            "services:\n  d:\n    profiles: [drivers]\n    x-coral:\n"
            "      command: ['{python}', '{plugin}']\n",
            None,
            r"compose.yaml:5: service d: x-coral.command has placeholder \{plugin\}; known: \{python\}",
            id="unknown command placeholder",
        ),
        pytest.param(
            "x-coral:\n  ready_timeout_s: -5\nservices: {}\n",
            None,
            r"compose.yaml:2: ready_timeout_s must be a positive number, not '-5'",
            id="negative timeout",
        ),
        pytest.param(
            "services:\n  e:\n    profiles: [executors]\n    x-coral:\n      rate: .inf\n",
            None,
            r"compose.yaml:5: rate must be a positive number up to 1000, not '.inf'",
            id="infinite rate",
        ),
    ],
)
def test_a_file_coral_cannot_run_is_refused_with_file_and_line(
    tmp_path: Path, compose: str, dotenv: str | None, message: str
) -> None:
    file = _project(tmp_path, compose, **({".env": dotenv} if dotenv is not None else {}))
    with pytest.raises(ComposeError, match=message):
        parse_compose(file, {})


def test_environment_lists_commands_and_dotenv_values_are_read(tmp_path: Path) -> None:
    file = _project(
        tmp_path,
        'services:\n  d:\n    profiles: [drivers]\n    environment: [A=1, "B=${FROM_DOTENV}"]\n'
        "    x-coral:\n      command: ['{python}', '-m', 'thing', '--plugins', '{plugins}']\n",
        **{".env": "FROM_DOTENV=hello\n"},
    )
    service = parse_compose(file, {}).services[0]
    assert service.environment == {"A": "1", "B": "hello"}
    assert service.command == ["{python}", "-m", "thing", "--plugins", "{plugins}"]


def test_a_missing_tree_file_is_reported(tmp_path: Path) -> None:
    file = _project(tmp_path, "x-coral:\n  tree: other.xml\nservices:\n  e:\n    profiles: [executors]\n")
    with pytest.raises(ComposeError, match=r"compose.yaml:2: tree file .*other.xml does not exist"):
        parse_compose(file, {})


def test_a_folder_without_a_compose_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ComposeError, match="no compose file"):
        find_compose_file(tmp_path)


def test_a_folder_name_becomes_a_project_name_as_docker_compose_makes_it(tmp_path: Path) -> None:
    folder = tmp_path / "_Field.Trial 2"
    folder.mkdir()
    assert parse_compose(_project(folder, "services: {}\n"), {}).name == "fieldtrial2"
    nameless = tmp_path / "..."
    nameless.mkdir()
    with pytest.raises(ComposeError, match=r"folder name '...' gives no project name; set a top-level name"):
        parse_compose(_project(nameless, "services: {}\n"), {})
