"""A built-in node missing a port it cannot run without is refused at load time with file:line.

BT.CPP accepts these trees and fails only when the node is first ticked, possibly far into a
mission; `coral validate`, the executor and the operator refuse them before anything runs.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner
from coral_core import bt
from coral_core.command import main
from coral_operator.planning import validation

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "lidar-slam"

CASES = [
    ("Repeat", "num_cycles", "<Repeat>\n        <AlwaysSuccess/>\n      </Repeat>"),
    (
        "RetryUntilSuccessful",
        "num_attempts",
        "<RetryUntilSuccessful>\n        <AlwaysSuccess/>\n      </RetryUntilSuccessful>",
    ),
    ("Sleep", "msec", "<Sleep/>"),
    ("Timeout", "msec", "<Timeout>\n        <AlwaysSuccess/>\n      </Timeout>"),
    ("Delay", "delay_msec", "<Delay>\n        <AlwaysSuccess/>\n      </Delay>"),
    ("Precondition", "if", '<Precondition else="FAILURE">\n        <AlwaysSuccess/>\n      </Precondition>'),
    ("Script", "code", "<Script/>"),
    ("ScriptCondition", "code", "<ScriptCondition/>"),
]


def _tree(node: str) -> str:
    return (
        '<root BTCPP_format="4" main_tree_to_execute="Main">\n'
        '  <BehaviorTree ID="Main">\n'
        "    <Sequence>\n"
        f"      {node}\n"
        "    </Sequence>\n"
        "  </BehaviorTree>\n"
        "</root>\n"
    )


@pytest.mark.parametrize(("node", "port", "xml"), CASES, ids=[c[0] for c in CASES])
def test_a_missing_required_port_is_reported_with_its_line(node: str, port: str, xml: str) -> None:
    document = bt.load_tree_text(_tree(xml), filename="tree.xml")
    problems = [str(e) for e in bt.validate_document(document, bt.NodeRegistry.with_builtins())]
    assert problems == [f"tree.xml:4: <{node}> needs the port [{port}]; it has no default"]
    (operator_problem,) = validation.validate_tree(_tree(xml), "spec.tree.inline")
    assert (
        operator_problem.startswith("spec.tree.inline:4: ") and f"needs the port [{port}]" in operator_problem
    )


def test_a_port_given_or_remapped_satisfies_it() -> None:
    xml = '<Repeat num_cycles="{n}">\n        <Sleep msec="5"/>\n      </Repeat>'
    document = bt.load_tree_text(_tree(xml), filename="tree.xml")
    assert bt.validate_document(document, bt.NodeRegistry.with_builtins()) == []


def test_coral_validate_names_the_file_and_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CORAL_BAG", str(tmp_path / "bag"))
    project = tmp_path / "project"
    shutil.copytree(EXAMPLE, project)
    tree = project / "tree.xml"
    lines = tree.read_text().splitlines(keepends=True)
    at = next(i for i, line in enumerate(lines) if "<BehaviorTree" in line) + 1
    # A Sequence child right under the tree's first node keeps the tree's structure valid.
    first = lines[at]
    indent = first[: len(first) - len(first.lstrip())]
    opening = first.strip()
    assert opening.startswith("<") and not opening.endswith("/>"), opening
    lines.insert(at + 1, f"{indent}  <Sleep/>\n")
    tree.write_text("".join(lines))
    result = CliRunner().invoke(main, ["validate", str(project)])
    assert result.exit_code == 1, result.output
    assert f"{tree}:{at + 2}" in result.output and "needs the port [msec]" in result.output
