"""The robot side and the operator meet only in `coral_core`, and no module imports itself.

The rules are the import-linter contracts in `.importlinter` (issue 52): `coral_core` imports
neither side, the operator imports nothing of the robot side or ROS, the robot side nothing of
the operator, the testbed none of the operator, and the operator's layers import downwards only.
`lint-imports` checks them; these tests run it on the project and on copies of it with one
forbidden import added, so a contract that stopped matching anything would be seen. import-linter
does not look for import circles, so the last test finds them on grimp's graph of every module.
"""

from __future__ import annotations

import os
import runpy
import shutil
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[2]
LINT_IMPORTS = Path(sys.executable).parent / "lint-imports"
# Import package -> source root, as setup.py maps them.
SOURCE_ROOTS: dict[str, str] = runpy.run_path(str(ROOT / "setup.py"), run_name="setup_for_tests")[
    "PACKAGE_ROOTS"
]


def _lint_imports(pythonpath: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache", "--no-logo", str(ROOT / ".importlinter")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )


def test_every_contract_holds() -> None:
    result = _lint_imports()
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout and " kept" in result.stdout


def _copy_of_the_project(into: Path) -> Path:
    """The import packages laid out under their import names, found first through PYTHONPATH."""
    for package, folder in SOURCE_ROOTS.items():
        shutil.copytree(ROOT / folder, into / package, ignore=shutil.ignore_patterns("__pycache__"))
    return into


@pytest.mark.parametrize(
    ("module", "forbidden_import", "broken"),
    [
        (
            "coral/executor/kubernetes_sink.py",
            "from coral_operator.api import keys",
            "The robot side imports nothing of the operator or the testbed",
        ),
        (
            "coral_operator/api/system.py",
            "from coral.executor import running",
            "The operator imports nothing of the robot side, ROS or the testbed",
        ),
        (
            "coral_operator/planning/validation.py",
            "import rclpy",
            "The operator imports nothing of the robot side, ROS or the testbed",
        ),
        (
            "coral_core/bt/loader.py",
            "from coral_operator.api import keys",
            "coral_core imports neither side, nor ROS or a Kubernetes client",
        ),
        (
            "coral_testbed/missions/stack.py",
            "from coral_operator.planning import pods",
            "The testbed runs the operator from its image and chart, and imports none of it",
        ),
        (
            "coral_operator/status/conditions.py",
            "from coral_operator.reconcile import controller",
            "The operator's layers import downwards only",
        ),
    ],
    ids=[
        "robot imports operator",
        "operator imports executor",
        "operator imports ROS",
        "core imports operator",
        "testbed imports operator",
        "status imports reconcile",
    ],
)
def test_a_forbidden_import_breaks_its_contract(
    tmp_path: Path, module: str, forbidden_import: str, broken: str
) -> None:
    copy = _copy_of_the_project(tmp_path)
    target = copy / module
    # Appended at the end, so the module's own imports stay first and sorted.
    target.write_text(target.read_text() + f"\n{forbidden_import}  # noqa\n")
    result = _lint_imports(pythonpath=copy)
    assert result.returncode == 1, result.stdout + result.stderr
    # The contract named, and the import shown with its line (the core's also breaks the robot
    # side's contract, which imports the core).
    assert f"{broken} BROKEN" in result.stdout, result.stdout
    assert f"{forbidden_import.split()[1]}" in result.stdout.split("Broken contracts")[1], result.stdout


def _import_circles(graph: grimp.ImportGraph) -> list[list[str]]:
    """Every set of two or more modules that import each other through a chain (Tarjan's strongly
    connected components, without recursion)."""
    index: dict[str, int] = {}
    lowest: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    circles: list[list[str]] = []
    for start in sorted(graph.modules):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.find_modules_directly_imported_by(start))))]
        index[start] = lowest[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            module, imported = work[-1]
            following = next(imported, None)
            if following is not None:
                if following not in index:
                    index[following] = lowest[following] = len(index)
                    stack.append(following)
                    on_stack.add(following)
                    work.append((following, iter(sorted(graph.find_modules_directly_imported_by(following)))))
                elif following in on_stack:
                    lowest[module] = min(lowest[module], index[following])
                continue
            work.pop()
            if work:
                lowest[work[-1][0]] = min(lowest[work[-1][0]], lowest[module])
            if lowest[module] == index[module]:
                members = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    members.append(member)
                    if member == module:
                        break
                if len(members) > 1:
                    circles.append(sorted(members))
    return circles


def test_no_module_imports_itself_through_others() -> None:
    """Imports inside functions and under TYPE_CHECKING count: a circle hidden in a function is
    still one (`coral_core.bt`'s model, builder and validation were one until issue 52)."""
    graph = grimp.build_graph(*SOURCE_ROOTS, cache_dir=None)
    assert _import_circles(graph) == []


def test_the_circle_finder_finds_a_circle() -> None:
    graph = grimp.ImportGraph()
    for importer, imported in [("p.a", "p.b"), ("p.b", "p.c"), ("p.c", "p.a"), ("p.c", "p.d")]:
        graph.add_import(importer=importer, imported=imported)
    assert _import_circles(graph) == [["p.a", "p.b", "p.c"]]
