"""Halting cancels in-flight requests; a killed skillset fails its behavior fast and is reported
as `LibraryDegraded` (acceptance 4)."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
from fixtures.processes import Spawn

from .runtime_processes import (
    finish,
    records_of,
    start_executor,
    start_skillset,
    wait_until,
    write_tree,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SLOW_PARAMS = """
/**:
  ros__parameters:
    work_delay_s: 30.0
"""


def _slow_params(tmp_path: Path) -> Path:
    """Parameters under which the skillset's Count takes 30 s: long enough to halt or kill it mid-call."""
    params = tmp_path / "params.yaml"
    params.write_text(SLOW_PARAMS)
    return params


def _files(tmp_path: Path) -> tuple[Path, Path, Path, Path, Path]:
    """The plugin folder, the skillset's log, a tree that calls Count, the executor's status and log."""
    tree = write_tree(tmp_path / "tree.xml", '    <Count count="{c}"/>')
    status, log = tmp_path / "status.jsonl", tmp_path / "executor.log"
    return tmp_path / "plugins", tmp_path / "skillset.log", tree, status, log


def test_stopping_the_executor_halts_count_and_cancels_its_request_in_the_skillset(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins, skillset_log, tree, status, log = _files(tmp_path)
    start_skillset(spawned, ros_env, plugins, skillset_log, params=_slow_params(tmp_path))
    executor = start_executor(spawned, ros_env, tree, plugins, status, log)
    wait_until(
        lambda: "Count request started" in skillset_log.read_text(), 60, "the request to reach the skillset"
    )
    executor.send_signal(signal.SIGTERM)
    assert finish(executor, 30, log) == 128 + signal.SIGTERM, log.read_text()
    wait_until(
        lambda: "Count request cancelled after" in skillset_log.read_text(), 10, "the skillset's cancel"
    )
    text = skillset_log.read_text()
    assert "Cancelled 1 request(s) on /examples/count for /coral_executor" in text
    seconds = float(text.split("Count request cancelled after ")[1].split(" s")[0])
    assert seconds < 20.0, "the 30 s request stopped when the behavior was halted"
    count = [t["status"] for t in records_of(status, "transition") if t["node_id"] == "Count"]
    assert count == ["RUNNING", "IDLE"], "Count was halted, not failed"
    [finished] = records_of(status, "finished")
    assert finished["root"] == "HALTED"


def test_killing_the_skillset_mid_call_fails_the_behavior_within_its_timeout_and_reports_degraded(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins, skillset_log, tree, status, log = _files(tmp_path)
    skillset = start_skillset(spawned, ros_env, plugins, skillset_log, params=_slow_params(tmp_path))
    executor = start_executor(spawned, ros_env, tree, plugins, status, log)

    # Kill only once the executor has heard the skillset alive and the request is being served.
    wait_until(
        lambda: any(r["state"] == "alive" for r in records_of(status, "component")), 60, "the skillset alive"
    )
    wait_until(
        lambda: "Count request started" in skillset_log.read_text(), 60, "the request to reach the skillset"
    )
    killed_at = time.time()
    os.killpg(skillset.pid, signal.SIGKILL)
    assert finish(executor, 30, log) == 1, log.read_text()
    failed = [
        t for t in records_of(status, "transition") if t["node_id"] == "Count" and t["status"] == "FAILURE"
    ]
    assert failed and failed[0]["ts"] - killed_at < 5.0, "FAILURE within Count's 5 s timeout"
    degraded = [r for r in records_of(status, "condition") if r["type"] == "LibraryDegraded"]
    assert degraded and degraded[0]["status"] == "True"
    assert "examples (no heartbeat for" in degraded[0]["message"]
    states = [r["state"] for r in records_of(status, "component")]
    assert states[-2:] == ["alive", "degraded"]
    last = records_of(status, "status")[-1]
    assert "skillset examples is unavailable" in last["last_failure"]["message"]
    assert any(c["type"] == "LibraryDegraded" and c["status"] == "True" for c in last["conditions"])


def test_a_call_that_times_out_fails_with_a_message_and_is_cancelled_in_the_skillset(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins, skillset_log, tree, status, log = _files(tmp_path)
    start_skillset(spawned, ros_env, plugins, skillset_log, params=_slow_params(tmp_path))
    assert finish(start_executor(spawned, ros_env, tree, plugins, status, log), 60, log) == 1, log.read_text()
    last = records_of(status, "status")[-1]
    assert last["last_failure"]["message"] == "no response from /examples/count within 5 s"
    assert last["last_failure"]["node_id"] == "Count"
    wait_until(
        lambda: "Count request cancelled after" in skillset_log.read_text(), 10, "the skillset's cancel"
    )
