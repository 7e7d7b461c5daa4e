"""Which build-context files the builder sends, following .dockerignore as builders do."""

from __future__ import annotations

import pytest
from coral_testbed.images import dockerignore

PROJECT_RULES = ".git\n.venv\n**/__pycache__\n**/*.pyc\nout\ntests\n"


@pytest.mark.parametrize(
    ("rules", "path", "excluded"),
    [
        pytest.param(PROJECT_RULES, "components/coral/executor/cli.py", False, id="keep a source file"),
        pytest.param(PROJECT_RULES, ".venv/bin/python", True, id="leave out everything under a named folder"),
        pytest.param(
            PROJECT_RULES,
            "components/coral/__pycache__/cli.cpython-311.pyc",
            True,
            id="leave out a nested folder matched through **",
        ),
        pytest.param(PROJECT_RULES, "deep/a/b/c.pyc", True, id="match a file name at any depth through **"),
        pytest.param(PROJECT_RULES, "tests_data/x", False, id="not match a longer name that starts the same"),
        pytest.param("*.md\n!README.md", "README.md", False, id="bring back a file with a later ! rule"),
        pytest.param("*.md\n!README.md", "CHANGES.md", True, id="leave out other files of the pattern"),
        pytest.param("!README.md\n*.md", "README.md", True, id="let the last matching rule win"),
        pytest.param("docs/*.txt", "docs/sub/a.txt", False, id="keep * within one path element"),
        pytest.param("/out", "out/map.ply", True, id="ignore a leading slash"),
        pytest.param("# comment\n\n", "anything", False, id="skip comments and blank lines"),
        pytest.param("file?.txt", "file1.txt", True, id="match one character with ?"),
        pytest.param("[ab].txt", "c.txt", False, id="match character classes"),
    ],
)
def test_rules(rules: str, path: str, excluded: bool) -> None:
    assert dockerignore.is_excluded(dockerignore.parse(rules), path) is excluded


def test_a_walk_prunes_excluded_folders_only_without_exceptions() -> None:
    assert dockerignore.can_prune(dockerignore.parse(PROJECT_RULES), ".venv")
    assert not dockerignore.can_prune(dockerignore.parse(".venv\n!.venv/keep"), ".venv")
