"""The shipped alert rules pass Prometheus's own checks, fire as their tests say (`promtool test
rules` evaluates them over synthetic series), and each alert has its runbook in docs/metrics.md."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[3]
MONITORING = ROOT / "charts" / "coral-operator" / "monitoring"
RULES = MONITORING / "rules.yaml"


def _promtool() -> str:
    promtool = shutil.which("promtool")
    if promtool is None:
        pytest.skip("promtool comes with Debian's prometheus package (hack/setup-node-runtime.sh)")
    return promtool


def _run(*args: str) -> str:
    done = subprocess.run([_promtool(), *args], capture_output=True, text=True, cwd=MONITORING, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout + done.stderr


def test_promtool_check_rules_passes_on_the_shipped_rules() -> None:
    assert "SUCCESS" in _run("check", "rules", str(RULES))


def test_each_alert_fires_after_its_threshold_and_not_before() -> None:
    assert "SUCCESS" in _run("test", "rules", "rules_test.yaml")


def test_every_alert_has_a_runbook_paragraph_in_the_docs() -> None:
    alerts = [
        rule["alert"]
        for group in yaml.safe_load(RULES.read_text())["groups"]
        for rule in group["rules"]
        if "alert" in rule
    ]
    headings = set(re.findall(r"^### (\w+)$", (ROOT / "docs" / "metrics.md").read_text(), re.MULTILINE))
    assert alerts and set(alerts) <= headings, f"no runbook for {sorted(set(alerts) - headings)}"
