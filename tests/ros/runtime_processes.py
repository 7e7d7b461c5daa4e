"""Helpers for the runtime's process tests: start real skillset and executor processes, read status."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coral_testbed.waiting import wait_for
from fixtures.processes import Spawn

PYTHON = sys.executable
STARTUP_S = 60.0


def wait_until(predicate: Callable[[], Any], timeout_s: float, what: str) -> Any:
    """`wait_for` with the short interval a process's files and topics want."""
    return wait_for(predicate, timeout=timeout_s, interval=0.05, message=what)


def start_skillset(
    spawned: Spawn,
    env: dict[str, str],
    plugins: Path,
    log: Path,
    *,
    name: str | None = None,
    params: Path | None = None,
    wait_ready: bool = True,
) -> subprocess.Popen[Any]:
    args = [PYTHON, "-m", "coral_skillsets.examples", "--plugins", str(plugins)]
    if name:
        args += ["--name", name]
    if params:
        args += ["--params", str(params)]
    process = spawned(args, env=env, stdout=log.open("w"), stderr=subprocess.STDOUT)
    if wait_ready:
        ready = plugins / (name or "examples") / "ready"
        wait_until(lambda: ready.exists() or process.poll() is not None, STARTUP_S, f"{ready}")
        assert process.poll() is None, log.read_text()
    return process


def start_executor(
    spawned: Spawn,
    env: dict[str, str],
    tree: Path,
    plugins: Path,
    status: Path,
    log: Path,
    *extra: str,
) -> subprocess.Popen[Any]:
    args = [PYTHON, "-m", "coral.executor", "--tree", str(tree), "--plugins", str(plugins)]
    args += ["--status-jsonl", str(status), "--rate", "20", *extra]
    return spawned(args, env=env, stdout=log.open("w"), stderr=subprocess.STDOUT)


def read_records(status: Path) -> list[dict[str, Any]]:
    if not status.exists():
        return []
    records = []
    for line in status.read_text().splitlines():
        if line.strip():
            records.append(json.loads(line))
    return records


def records_of(status: Path, event: str) -> list[dict[str, Any]]:
    return [record for record in read_records(status) if record["event"] == event]


def finish(process: subprocess.Popen[Any], timeout_s: float, log: Path) -> int:
    try:
        return process.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"process did not finish in {timeout_s:g} s; log:\n{log.read_text()}") from None


def write_tree(path: Path, body: str) -> Path:
    path.write_text(
        f'<root BTCPP_format="4" main_tree_to_execute="Main">\n'
        f'  <BehaviorTree ID="Main">\n{body}\n  </BehaviorTree>\n</root>\n'
    )
    return path
