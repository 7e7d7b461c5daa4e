"""Helpers of the `coral run` process tests: the CLI command line, run records, process liveness."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any


def coral(*args: str) -> list[str]:
    return [sys.executable, "-m", "coral", *args]


def run_records(env: dict[str, str]) -> list[dict[str, Any]]:
    root = Path(env["CORAL_STATE_DIR"]) / "runs"
    return [json.loads(p.read_text()) for p in sorted(root.glob("*/run.json"))] if root.is_dir() else []


def component_pids(env: dict[str, str]) -> list[int]:
    return [c["pid"] for r in run_records(env) for c in r["components"] if c.get("pid")]


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def interrupt(process: subprocess.Popen[Any]) -> None:
    process.send_signal(signal.SIGINT)


def tree_running(env: dict[str, str]) -> bool:
    """True once an executor of a recorded run reported its tree RUNNING."""
    root = Path(env["CORAL_STATE_DIR"]) / "runs"
    for status in root.glob("*/status-*.jsonl"):
        for line in status.read_text().splitlines():
            try:
                record = json.loads(line)
            except ValueError:
                continue
            if record.get("event") == "status" and record.get("root") == "RUNNING":
                return True
    return False
