"""The operator's layers import downwards only, and kopf/kubernetes stay in kube/ and handlers/.

Layers, top to bottom: handlers > kube > planning > status > api (STYLE.md). `status` may read the
planning records it summarizes (`planning.observed`, `planning.startup`, `planning.naming`).
"""

from __future__ import annotations

import ast
from pathlib import Path

import coral_operator

PACKAGE = Path(coral_operator.__file__).parent
ORDER = ["api", "status", "planning", "kube", "handlers"]
ALLOWED_UPWARD = {("status", "planning")}


def _imports(path: Path) -> set[str]:
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
    return found


def test_no_layer_imports_a_higher_one_and_no_client_below_kube() -> None:
    problems = []
    for layer in ORDER:
        for path in (PACKAGE / layer).rglob("*.py"):
            for name in _imports(path):
                top = name.split(".")[0]
                if top in ("kopf", "kubernetes") and ORDER.index(layer) < ORDER.index("kube"):
                    problems.append(f"{path.relative_to(PACKAGE)} imports {name}")
                if name.startswith("coral_operator."):
                    target = name.split(".")[1]
                    if target in ORDER and ORDER.index(target) > ORDER.index(layer):
                        if (layer, target) not in ALLOWED_UPWARD:
                            problems.append(f"{path.relative_to(PACKAGE)} imports {name}")
    assert not problems, problems


def test_kopf_is_imported_only_by_handlers() -> None:
    offenders = [
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if "kopf" in {n.split(".")[0] for n in _imports(path)}
        and path.parent.name != "handlers"
        and path.name != "main.py"
    ]
    assert offenders == []
