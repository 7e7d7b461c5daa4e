"""Maps the project's import packages onto their folders (see the README's Layout section).

Each role has one import package living in its own source root, so the folder names
(`operator/`, `components/skillsets/`, ...) never become import names themselves.
"""

from pathlib import Path

from setuptools import find_packages, setup

PACKAGE_ROOTS = {
    "coral": "components/coral",
    "coral_skillsets": "components/skillsets",
    "coral_drivers": "components/drivers",
    "coral_operator": "operator/coral_operator",
    "coral_testbed": "testbed/coral_testbed",
}


def _packages() -> list[str]:
    found: list[str] = []
    for name, path in PACKAGE_ROOTS.items():
        # Container images copy only the roots they run (no test tooling); absent ones are skipped.
        if not (Path(__file__).parent / path).is_dir():
            continue
        found.append(name)
        found.extend(f"{name}.{sub}" for sub in find_packages(path))
    return found


setup(packages=_packages(), package_dir=PACKAGE_ROOTS)
