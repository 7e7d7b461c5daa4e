"""The GitOps clients of docs/verdicts.md, run for real on live objects.

kstatus (sigs.k8s.io/cli-utils), the Argo CD health script in gopher-lua with Argo CD's sandbox,
and Flux's `healthCheckExprs` in cel-go are one Go binary, `coral-verdicts`, built and cached by
hack/build-verdict-tools.sh; `coral rollout status` is the CLI itself.
"""

from __future__ import annotations

import functools
import json
import re
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from click.testing import CliRunner
from coral_operator.rollout_cli import rollout as rollout_group
from coral_testbed.waiting import wait_for

ROOT = Path(__file__).resolve().parents[3]
TABLE = ROOT / "docs" / "verdicts.md"
HEALTH_LUA = ROOT / "charts" / "coral-operator" / "argocd" / "health.lua"
FLUX_KUSTOMIZATION = ROOT / "examples" / "gitops" / "flux" / "fleet-kustomization.yaml"
KINDS = ("CoralSystem", "CoralInstance")


@dataclass(frozen=True)
class Verdict:
    """What one client says of one object: kstatus, Flux CEL and Argo CD statuses."""

    kstatus: str
    flux: str
    argo: str


@functools.cache
def verdicts_binary() -> str:
    """The coral-verdicts binary, built on first use (a minute) and cached by version."""
    built = subprocess.run(
        ["bash", str(ROOT / "hack" / "build-verdict-tools.sh")],
        check=True,
        capture_output=True,
        text=True,
        timeout=900,
    )
    return built.stdout.strip().splitlines()[-1]


def flux_expressions() -> dict[str, dict[str, str]]:
    """The `healthCheckExprs` of the Flux example, by kind."""
    spec = yaml.safe_load(FLUX_KUSTOMIZATION.read_text())["spec"]
    return {
        entry["kind"]: {key: entry.get(key, "") for key in ("current", "failed", "inProgress")}
        for entry in spec["healthCheckExprs"]
    }


def judge_all(objects: list[dict[str, Any]]) -> list[dict[str, dict[str, str]]]:
    """Every client's full judgement (status and message) of each object."""
    request = {"objects": objects, "lua": HEALTH_LUA.read_text(), "cel": flux_expressions()}
    result = subprocess.run(
        [verdicts_binary()], input=json.dumps(request), check=True, capture_output=True, text=True, timeout=60
    )
    return json.loads(result.stdout)


def judge(obj: dict[str, Any]) -> Verdict:
    """The three statuses one object gets."""
    found = judge_all([obj])[0]
    return Verdict(
        kstatus=found["kstatus"]["status"], flux=found["flux"]["status"], argo=found["argo"]["status"]
    )


@dataclass(frozen=True)
class Row:
    state: str
    kind: str
    expected: Verdict
    rollout_status: str | None
    """`exit N: complete|waiting|failed`, or None for a kind without rollouts."""


def read_table(path: Path = TABLE) -> list[Row]:
    """The verdict table of docs/verdicts.md."""
    rows = []
    for line in path.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 6 or cells[1] not in KINDS:
            continue
        state, kind, kstatus, flux, argo, rollout_status = cells
        rows.append(
            Row(
                state=state,
                kind=kind,
                expected=Verdict(kstatus=kstatus, flux=flux, argo=argo),
                rollout_status=None if rollout_status == "-" else rollout_status,
            )
        )
    return rows


def rollout_status(env: dict[str, str], namespace: str, name: str) -> str:
    """`coral rollout status NAME` as `exit N: complete|waiting|failed`, from the real CLI."""
    result = CliRunner().invoke(rollout_group, ["status", name, "-n", namespace], env=env)
    output = result.output
    if result.exit_code == 0 and re.search(r"^\s+complete:", output, re.MULTILINE):
        word = "complete"
    elif "failed" in output and result.exit_code != 0:
        word = "failed"
    else:
        word = "waiting"
    return f"exit {result.exit_code}: {word}"


def wait_for_rollout(
    fleet: Any, predicate: Callable[[dict[str, str], dict[str, Any]], bool], message: str
) -> None:
    """Waits until `predicate(revisions by robot, status.rollout)` holds."""
    wait_for(
        lambda: predicate(fleet.revisions(), fleet.rollout()),
        timeout=120,
        interval=0.3,
        message=lambda: f"{message}; rollout={fleet.rollout()}",
    )
