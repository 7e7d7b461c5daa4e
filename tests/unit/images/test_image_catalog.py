"""The image catalog covers every Dockerfile in the repository and matches what each declares."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from coral_testbed.images import catalog, dockerfiles

ROOT = Path(__file__).resolve().parents[3]


def test_every_dockerfile_in_the_repository_has_an_image() -> None:
    listed = subprocess.run(
        ["git", "ls-files", "*Dockerfile"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    assert listed, "git lists no Dockerfile"
    assert sorted(listed) == sorted(spec.dockerfile for spec in catalog.IMAGES)


@pytest.mark.parametrize("spec", catalog.IMAGES, ids=lambda spec: spec.name)
def test_each_parent_is_a_declared_build_argument_used_by_from(spec: catalog.ImageSpec) -> None:
    parsed = dockerfiles.read(ROOT / spec.dockerfile)
    froms = [i.arguments for i in parsed.of("FROM")]
    for arg in spec.parents:
        assert arg in parsed.args(), f"{spec.dockerfile} declares no ARG {arg}"
        assert f"${{{arg}}}" in froms, f"{spec.dockerfile} does not start FROM ${{{arg}}}"


@pytest.mark.parametrize("path", ["components/Dockerfile", "operator/Dockerfile"])
def test_project_bases_default_to_the_official_python_image(path: str) -> None:
    assert dockerfiles.read(ROOT / path).args()["BASE"] == "python:3.11-slim-bookworm"


def test_children_default_to_their_parents_published_name() -> None:
    by_name = catalog.by_name()
    for spec in catalog.IMAGES:
        declared = dockerfiles.read(ROOT / spec.dockerfile).args()
        for arg, parent in spec.parents.items():
            if arg != "BASE":
                assert declared[arg] == by_name[parent].reference, f"{spec.dockerfile}: ARG {arg}"


def test_an_image_comes_with_its_parents_first() -> None:
    names = [spec.name for spec in catalog.with_parents(["operator", "executor"])]
    assert names == ["python", "runtime", "executor", "operator"]


def test_an_unknown_image_is_named_in_the_error() -> None:
    with pytest.raises(KeyError, match="no image named 'exectuor'; known: python"):
        catalog.with_parents(["exectuor"])
