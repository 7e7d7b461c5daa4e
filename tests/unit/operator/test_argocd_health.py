"""The Argo CD health check maps Coral conditions to Healthy, Progressing and Degraded on its fixtures."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

lupa = pytest.importorskip("lupa", reason="lupa (test extra) runs the Lua health check")

ARGOCD = Path(__file__).resolve().parents[3] / "charts" / "coral-operator" / "argocd"
CASES = yaml.safe_load((ARGOCD / "health_test.yaml").read_text())["tests"]


def _health(obj: dict[str, Any]) -> dict[str, str]:
    runtime = lupa.LuaRuntime(unpack_returned_tuples=True)

    def to_lua(value: Any) -> Any:
        # Argo CD hands the script plain Lua tables, with lists as 1-based arrays.
        if isinstance(value, dict):
            return runtime.table_from({k: to_lua(v) for k, v in value.items()})
        if isinstance(value, list):
            return runtime.table_from([to_lua(v) for v in value])
        return value

    # Argo CD's sandbox opens only base, table and a safe `os`: a script that leans on the string
    # library works here but fails in Argo CD, so it is taken away.
    hidden = ("string", "io", "os", "debug", "coroutine", "utf8", "math", "require", "dofile", "loadfile")
    for library in hidden:
        runtime.globals()[library] = None
    runtime.globals().obj = to_lua(obj)
    result = runtime.execute((ARGOCD / "health.lua").read_text())
    return {"status": result["status"], "message": result["message"]}


@pytest.mark.parametrize("case", CASES, ids=[c["inputPath"] for c in CASES])
def test_the_health_check_on_its_fixture(case: dict[str, Any]) -> None:
    obj = yaml.safe_load((ARGOCD / case["inputPath"]).read_text())
    assert _health(obj) == case["healthStatus"]


def test_every_status_argo_cd_needs_is_covered() -> None:
    assert {c["healthStatus"]["status"] for c in CASES} >= {"Healthy", "Progressing", "Degraded", "Suspended"}
