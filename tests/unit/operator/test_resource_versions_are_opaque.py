"""resourceVersions are compared for equality only (issue 52, acceptance 4).

Kubernetes API conventions make a resourceVersion opaque: a client may not assume it is an
integer or that a larger one is newer. The operator used to read its own status writes back as
`int(observed) > int(written)`. It now knows the versions an object had before a write, and any
other version is the write's or a later one. The versions below are not numbers, so no ordering
could pass these tests; the last tests look for ordering comparisons in the operator's source.
"""

from __future__ import annotations

import ast
from pathlib import Path

import coral_operator
import pytest
from coral_operator.planning.observed import InstanceRecord
from coral_operator.reconcile.unseen_writes import MovedInstances, StatusWrites

PACKAGE = Path(coral_operator.__file__).parent
OURS = {"conditions": [{"type": "Ready", "status": "True"}]}
FORGED = {"conditions": [{"type": "Ready", "status": "False"}]}


def test_an_index_still_at_the_version_the_write_replaced_is_shown_the_write() -> None:
    statuses = StatusWrites()
    statuses.remember("i1", "qx", OURS, replaced="mb")
    assert statuses.unseen("i1", "mb") == OURS
    assert statuses.observed("i1", "mb", FORGED) == OURS


def test_the_written_version_or_any_later_one_is_the_truth() -> None:
    statuses = StatusWrites()
    statuses.remember("i1", "qx", OURS, replaced="mb")
    assert statuses.unseen("i1", "qx") is None
    # An executor that forged the operator's part after the write is seen, and corrected.
    assert statuses.observed("i1", "zz", FORGED) == FORGED


def test_a_second_write_before_the_index_caught_up_keeps_both_hidden_versions() -> None:
    statuses = StatusWrites()
    statuses.remember("i1", "v1", {"step": 1}, replaced="v0")
    # The next pass read the index still at v0: the index may show v0, then v1, before v2.
    statuses.remember("i1", "v2", OURS, replaced="v0")
    assert statuses.unseen("i1", "v0") == OURS
    assert statuses.unseen("i1", "v1") == OURS
    assert statuses.unseen("i1", "v2") is None
    # Once a pass read the index at the write's version, only that version is from before.
    statuses.remember("i1", "v3", {"step": 3}, replaced="v2")
    assert statuses.unseen("i1", "v1") is None
    assert statuses.unseen("i1", "v2") == {"step": 3}


def _record(version: str, uid: str = "i1") -> InstanceRecord:
    return InstanceRecord(
        name="sys-r1", namespace="ns", uid=uid, generation=2, spec={}, status={}, resource_version=version
    )


def test_a_moved_instance_counts_until_the_index_leaves_the_version_it_had_before() -> None:
    moved_instances = MovedInstances(clock=lambda: 0.0)
    key = ("ns", "sys-r1")
    moved = _record("qx")
    moved_instances.remember(moved, replaced="mb")
    assert moved_instances.latest(key, _record("mb")) is moved
    later = _record("zz")
    assert moved_instances.latest(key, later) is later
    assert moved_instances.latest(key, _record("mb")).resource_version == "mb", "forgotten once caught up"


ORDERING = (ast.Lt, ast.LtE, ast.Gt, ast.GtE)
CONVERSIONS = {"int", "float", "sorted", "max", "min"}
SPELLINGS = ("resource_version", "resourceversion")


def _names(node: ast.AST) -> set[str]:
    """Identifiers, attributes and strings in `node`."""
    found: set[str] = set()
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name):
            found.add(sub.id)
        elif isinstance(sub, ast.Attribute):
            found.add(sub.attr)
        elif isinstance(sub, ast.Constant) and isinstance(sub.value, str):
            found.add(sub.value)
    return found


def _reads_a_version(value: ast.AST, held: set[str]) -> bool:
    """`value` is a version itself: a name holding one, `x.resource_version`, `x["resourceVersion"]`
    or `x.get("resourceVersion")` (not any expression that merely uses one)."""
    if isinstance(value, ast.Name):
        return value.id in held
    if isinstance(value, ast.Attribute):
        return value.attr.lower() in SPELLINGS
    key = (
        value.slice
        if isinstance(value, ast.Subscript)
        else value.args[0]
        if isinstance(value, ast.Call) and getattr(value.func, "attr", "") == "get" and value.args
        else None
    )
    return isinstance(key, ast.Constant) and str(key.value).lower() in SPELLINGS


def _version_names(scope: ast.AST) -> set[str]:
    """Names that hold a resourceVersion in a function: its parameters when its docstring speaks of
    one, and what is assigned a version."""
    held: set[str] = set()
    if isinstance(scope, ast.FunctionDef | ast.AsyncFunctionDef):
        doc = (ast.get_docstring(scope) or "").lower()
        if any(spelling in doc for spelling in SPELLINGS):
            held |= {arg.arg for arg in [*scope.args.args, *scope.args.kwonlyargs]} - {"self"}
        statements = list(ast.walk(scope))
    else:
        statements = list(getattr(scope, "body", []))
    for _ in range(2):  # a version copied once more is still a version
        for node in statements:
            if isinstance(node, ast.Assign) and _reads_a_version(node.value, held):
                held |= {target.id for target in node.targets if isinstance(target, ast.Name)}
    return held


def _is_version(node: ast.AST, held: set[str]) -> bool:
    names = _names(node)
    return bool(names & held) or any(spelling in name.lower() for name in names for spelling in SPELLINGS)


def ordering_of_versions(source: str) -> list[int]:
    """Lines that order resourceVersions or turn one into a number."""
    tree = ast.parse(source)
    found: set[int] = set()
    scopes = [tree, *(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef))]
    for scope in scopes:
        held = _version_names(scope)
        for node in ast.walk(scope):
            if isinstance(node, ast.Compare) and any(isinstance(op, ORDERING) for op in node.ops):
                if any(_is_version(side, held) for side in [node.left, *node.comparators]):
                    found.add(node.lineno)
            elif isinstance(node, ast.Call) and getattr(node.func, "id", "") in CONVERSIONS:
                if any(_is_version(arg, held) for arg in [*node.args, *(k.value for k in node.keywords)]):
                    found.add(node.lineno)
            elif isinstance(node, ast.Attribute) and node.attr in ("isdigit", "isnumeric", "isdecimal"):
                if _is_version(node.value, held):
                    found.add(node.lineno)
    return sorted(found)


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_orders_resource_versions(path: Path) -> None:
    assert ordering_of_versions(path.read_text()) == []


@pytest.mark.parametrize(
    "source",
    [
        "newer = int(body['metadata']['resourceVersion']) > int(written)",
        "if indexed.resource_version >= written.resource_version: pass",
        "latest = max(records, key=lambda r: r.resource_version)",
        "ok = resource_version.isdigit()",
        "version = body['metadata'].get('resourceVersion')\nnewer = version > seen",
    ],
)
def test_the_search_finds_an_ordering_of_versions(source: str) -> None:
    assert ordering_of_versions(source) == [source.count("\n") + 1], "the last line orders versions"


def test_the_search_finds_the_comparison_issue_52_removed() -> None:
    """`status.ownership.at_or_after` as it was: the versions arrive as plain parameters."""
    removed = '''
def at_or_after(observed: str | None, written: str | None) -> bool:
    """Whether an object at resourceVersion `observed` already includes the write that returned
    `written`."""
    if observed is None or written is None:
        return False
    if observed == written:
        return True
    return observed.isdigit() and written.isdigit() and int(observed) > int(written)
'''
    assert ordering_of_versions(removed) == [9]


def test_the_search_leaves_equality_and_other_numbers_alone() -> None:
    source = '''
def caught_up(indexed, written, predating):
    """Whether the index holds a resourceVersion other than those before the write."""
    return indexed.resource_version not in predating or indexed.resource_version == written
version = metadata.get("resourceVersion")
same = version == "7"
later = generation > 3
status = memory.observed_status(uid, version, status)
late = max(wake_at - now, 0.0) > status["x"]
'''
    assert ordering_of_versions(source) == []
