"""The installed project keeps its import packages apart from the standard library, and the `coral`
command offers the verbs of the parts that are installed, registered where they live."""

import importlib
import operator
import runpy
import subprocess
import sys
from pathlib import Path

import click
from coral_core import command

ROOT = Path(__file__).resolve().parents[2]
SETUP = runpy.run_path(str(ROOT / "setup.py"), run_name="setup_for_tests")


def test_the_operator_folder_does_not_shadow_the_standard_library_operator_module() -> None:
    assert operator.__file__ is not None
    assert "site-packages" not in operator.__file__
    assert hasattr(operator, "itemgetter")


def test_every_role_package_imports() -> None:
    for name in SETUP["PACKAGE_ROOTS"]:
        assert importlib.import_module(name).__doc__


def test_the_coral_command_lists_its_verbs() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "coral", "--help"], capture_output=True, text=True, check=True
    )
    for verb in ("run", "executor", "operator", "rollout", "dev-cluster"):
        assert f"  {verb} " in result.stdout, result.stdout


def test_every_installed_verb_is_a_click_command_of_its_own_part() -> None:
    verbs = command.installed_verbs()
    # This checkout has every root, so every registered verb is installed.
    registered = SETUP["entry_points"](list(SETUP["PACKAGE_ROOTS"]))["coral.verbs"]
    assert sorted(verbs) == sorted(verb.split(" = ")[0] for verb in registered)
    for name, entry in verbs.items():
        assert isinstance(entry.load(), click.Command), name


def test_a_copy_without_the_testbed_registers_none_of_its_verbs() -> None:
    """What an image installs: its roots only (the operator image has no testbed, no robot side)."""
    roots = ["coral_core", "coral_operator"]
    verbs = SETUP["entry_points"](roots)["coral.verbs"]
    operator_verbs = {"operator", "convert", "crds", "rollout", "halt", "resume", "groot2", "tree", "config"}
    # `logs` is coral_core's: it offers whichever side's logs are installed (coral_core.logs_verb).
    assert {verb.split(" = ")[0] for verb in verbs} == operator_verbs | {"logs"}
    assert SETUP["entry_points"](roots)["coral.logs"] == ["system = coral_operator.logs_cli:LOGS_OF_SYSTEMS"]
    assert "coral.components" not in SETUP["entry_points"](roots)
    assert SETUP["entry_points"](roots)["console_scripts"] == ["coral = coral_core.command:main"]


def test_each_entry_point_names_a_module_of_the_root_that_registers_it() -> None:
    for root, groups in SETUP["ENTRY_POINTS"].items():
        for entries in groups.values():
            for entry in entries:
                target = entry.split(" = ")[1]
                assert target.split(".")[0] == root, entry


def test_an_unknown_verb_is_refused() -> None:
    result = subprocess.run([sys.executable, "-m", "coral", "no-such-verb"], capture_output=True, text=True)
    assert result.returncode == 2 and "No such command 'no-such-verb'" in result.stderr
