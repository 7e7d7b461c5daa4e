"""The operator's handlers stay glue, and no module keeps state between calls.

Which layer may import which is not checked here: the import-linter contracts in `.importlinter`
hold docs/architecture.md's "Layers and their import rules" (`tests/unit/test_import_contracts.py`).
"""

from __future__ import annotations

import ast
from pathlib import Path

import coral_operator

PACKAGE = Path(coral_operator.__file__).parent
# Objects that carry state between calls when made at import time.
STATEFUL_CALLS = {
    "Lock",
    "RLock",
    "Condition",
    "Event",
    "Timer",
    "Thread",
    "ThreadPoolExecutor",
    "WorkQueue",
    "Queue",
    "dict",
    "set",
    "list",
    "defaultdict",
    "deque",
    "OrderedDict",
    "Counter",
}
MUTATORS = {
    "add",
    "append",
    "clear",
    "discard",
    "extend",
    "insert",
    "pop",
    "popitem",
    "remove",
    "setdefault",
    "update",
}


def test_handlers_are_glue_only_under_400_lines() -> None:
    lines = sum(len(path.read_text().splitlines()) for path in (PACKAGE / "handlers").rglob("*.py"))
    assert lines < 400, f"handlers/ has {lines} lines; the logic belongs in reconcile/, planning/ or kube/"


def _module_state(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    where = str(path.relative_to(PACKAGE))
    problems = []
    module_names: set[str] = set()
    for node in tree.body:
        targets = (
            node.targets
            if isinstance(node, ast.Assign)
            else [node.target]
            if isinstance(node, ast.AnnAssign)
            else []
        )
        value = getattr(node, "value", None)
        for target in targets:
            if isinstance(target, ast.Name):
                module_names.add(target.id)
        if isinstance(value, ast.Call):
            func = value.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if called in STATEFUL_CALLS:
                problems.append(f"{where}:{node.lineno} makes a {called} at import time")
    for node in ast.walk(tree):
        if isinstance(node, ast.Global):
            problems.append(f"{where}:{node.lineno} rebinds module globals {node.names}")
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for inner in ast.walk(node):
                if (
                    isinstance(inner, ast.Call)
                    and isinstance(inner.func, ast.Attribute)
                    and isinstance(inner.func.value, ast.Name)
                    and inner.func.value.id in module_names
                    and inner.func.attr in MUTATORS
                ):
                    problems.append(f"{where}:{inner.lineno} changes module-level {inner.func.value.id}")
                if isinstance(inner, ast.Subscript | ast.Attribute) and isinstance(
                    inner.ctx, ast.Store | ast.Del
                ):
                    base = inner.value
                    if isinstance(base, ast.Name) and base.id in module_names:
                        problems.append(f"{where}:{inner.lineno} changes module-level {base.id}")
    return problems


def test_no_module_holds_mutable_state_between_calls() -> None:
    """What must be remembered between passes lives in one injected object (`reconcile.memory`)."""
    problems = [problem for path in sorted(PACKAGE.rglob("*.py")) for problem in _module_state(path)]
    assert problems == []
