"""The Argo CD health check maps Coral conditions to Healthy, Progressing and Degraded on its fixtures."""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from fixtures import argocd

pytest.importorskip("lupa", reason="lupa (test extra) runs the Lua health check")

CASES = yaml.safe_load((argocd.ARGOCD / "health_test.yaml").read_text())["tests"]


@pytest.mark.parametrize("case", CASES, ids=[c["inputPath"] for c in CASES])
def test_the_health_check_on_its_fixture(case: dict[str, Any]) -> None:
    obj = yaml.safe_load((argocd.ARGOCD / case["inputPath"]).read_text())
    assert argocd.health(obj) == case["healthStatus"]


def test_every_status_argo_cd_needs_is_covered() -> None:
    assert {c["healthStatus"]["status"] for c in CASES} >= {"Healthy", "Progressing", "Degraded", "Suspended"}
