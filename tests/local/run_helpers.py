"""Helpers of the `coral run` process tests: the CLI command line, run records, process liveness."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coral.local import state

StartRun = Callable[..., "subprocess.Popen[str]"]
"""The `start_run` fixture: `start_run(example, output, *extra)` starts `coral run` (see conftest)."""


def coral(*args: str) -> list[str]:
    return [sys.executable, "-m", "coral", *args]


def run_records(env: dict[str, str]) -> list[dict[str, Any]]:
    root = Path(env["CORAL_STATE_DIR"]) / "runs"
    return [json.loads(p.read_text()) for p in sorted(root.glob("*/run.json"))] if root.is_dir() else []


def component_pids(env: dict[str, str]) -> list[int]:
    return [c["pid"] for r in run_records(env) for c in r["components"] if c.get("pid")]


def alive(pid: int) -> bool:
    return state.pid_alive(pid)


def interrupt(process: subprocess.Popen[Any]) -> None:
    process.send_signal(signal.SIGINT)


def _status_records(env: dict[str, str]) -> list[dict[str, Any]]:
    records: list[dict[str, Any]] = []
    for status in (Path(env["CORAL_STATE_DIR"]) / "runs").glob("*/status-*.jsonl"):
        for line in status.read_text().splitlines():
            try:
                records.append(json.loads(line))
            except ValueError:
                continue
    return records


def node_successes(env: dict[str, str], node_id: str) -> int:
    """How often nodes of type `node_id` succeeded so far, from the executors' status records."""
    return sum(
        1
        for record in _status_records(env)
        if record.get("event") == "transition"
        and record.get("node_id") == node_id
        and record.get("status") == "SUCCESS"
    )


def tree_running(env: dict[str, str]) -> bool:
    """True once an executor of a recorded run reported its tree RUNNING."""
    return any(
        record.get("event") == "status" and record.get("root_status") == "RUNNING"
        for record in _status_records(env)
    )
