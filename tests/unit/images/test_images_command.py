"""`coral images`: the verbs list the catalog and refuse unknown names before building anything."""

from __future__ import annotations

from click.testing import CliRunner
from coral_core.command import main
from coral_testbed.images import catalog


def test_list_names_every_image_with_its_dockerfile() -> None:
    result = CliRunner().invoke(main, ["images", "list"])
    assert result.exit_code == 0, result.output
    for spec in catalog.IMAGES:
        assert f"{spec.reference}" in result.output and spec.dockerfile in result.output


def test_build_refuses_an_unknown_image_by_name() -> None:
    result = CliRunner().invoke(main, ["images", "build", "--no-push", "exectuor"])
    assert result.exit_code == 2
    assert "unknown image exectuor; known: python, runtime" in result.output


def test_registry_refuses_a_bad_address() -> None:
    result = CliRunner().invoke(main, ["images", "registry", "up", "--registry", "localhost"])
    assert result.exit_code == 1
    assert "registry address 'localhost' is not HOST:PORT" in result.output
