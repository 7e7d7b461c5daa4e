"""An image's fingerprint changes with what its build reads, and only with that."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral_testbed.images import fingerprints


@pytest.fixture
def context(tmp_path: Path) -> Path:
    (tmp_path / "app").mkdir()
    (tmp_path / "app" / "main.py").write_text("print('hi')\n")
    (tmp_path / "app" / "__pycache__").mkdir()
    (tmp_path / "app" / "__pycache__" / "main.pyc").write_bytes(b"\0")
    (tmp_path / "notes.txt").write_text("not copied\n")
    (tmp_path / ".dockerignore").write_text("**/__pycache__\n")
    (tmp_path / "Dockerfile").write_text("ARG BASE=python:3.11-slim-bookworm\nFROM ${BASE}\nCOPY app /app\n")
    return tmp_path


def _fingerprint(context: Path, parent: str = "sha256:aaa") -> str:
    return fingerprints.compute(context / "Dockerfile", context, build_args={}, parent_ids={"BASE": parent})


def test_the_same_inputs_give_the_same_fingerprint(context: Path) -> None:
    assert _fingerprint(context) == _fingerprint(context)


@pytest.mark.parametrize(
    "change",
    [
        pytest.param(lambda c: (c / "app" / "main.py").write_text("print('bye')\n"), id="a copied file"),
        pytest.param(lambda c: (c / "app" / "extra.py").write_text(""), id="a new file in a copied folder"),
        pytest.param(lambda c: (c / "app" / "main.py").chmod(0o755), id="a copied file's mode"),
        pytest.param(lambda c: (c / "Dockerfile").write_text("FROM scratch\nCOPY app /"), id="Dockerfile"),
    ],
)
def test_a_change_the_build_can_see_changes_the_fingerprint(context: Path, change: object) -> None:
    before = _fingerprint(context)
    change(context)  # type: ignore[operator]
    assert _fingerprint(context) != before


@pytest.mark.parametrize(
    "change",
    [
        pytest.param(lambda c: (c / "notes.txt").write_text("edited\n"), id="a file no COPY uses"),
        pytest.param(lambda c: (c / "app" / "__pycache__" / "main.pyc").write_bytes(b"\1"), id="ignored"),
    ],
)
def test_a_change_the_build_cannot_see_keeps_the_fingerprint(context: Path, change: object) -> None:
    before = _fingerprint(context)
    change(context)  # type: ignore[operator]
    assert _fingerprint(context) == before


def test_a_rebuilt_parent_changes_the_fingerprint(context: Path) -> None:
    assert _fingerprint(context, parent="sha256:aaa") != _fingerprint(context, parent="sha256:bbb")


def test_only_the_files_copy_names_count(context: Path) -> None:
    from coral_testbed.images import dockerfiles

    parsed = dockerfiles.read(context / "Dockerfile")
    assert fingerprints.context_files(parsed, context) == ["app/main.py"]
