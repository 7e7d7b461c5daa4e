"""The installed project keeps its import packages apart from the standard library."""

import importlib
import operator
import subprocess
import sys


def test_the_operator_folder_does_not_shadow_the_standard_library_operator_module() -> None:
    assert operator.__file__ is not None
    assert "site-packages" not in operator.__file__
    assert hasattr(operator, "itemgetter")


def test_every_role_package_imports() -> None:
    for name in ("coral", "coral_operator", "coral_testbed", "coral_skillsets", "coral_drivers"):
        assert importlib.import_module(name).__doc__


def test_the_coral_command_lists_its_verbs() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "coral", "--help"], capture_output=True, text=True, check=True
    )
    assert "dev-cluster" in result.stdout
