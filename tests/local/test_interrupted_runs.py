"""Stopping a run: SIGINT, a crashing skillset, `coral stop`; never a process left behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from coral_testbed.waiting import wait_for
from fixtures.processes import Spawn
from run_helpers import StartRun, alive, component_pids, coral, interrupt, run_records, tree_running

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_sigint_mid_mission_stops_every_component_and_exits_non_zero(
    start_run: StartRun, run_env: dict[str, str], example_copy: Callable[..., Path], tmp_path: Path
) -> None:
    example = example_copy(rate=0.2)  # 40 scans over 20 s: still running when interrupted
    process = start_run(example, tmp_path / "out")
    wait_for(lambda: tree_running(run_env), timeout=120, message="the mission to be running")
    pids = component_pids(run_env)
    assert len(pids) == 4 and all(alive(pid) for pid in pids)
    # Each component leads its own process group (a stop reaches whatever it started) inside the
    # run's session: the kernel's autogroup scheduler shares the CPU between sessions, so the whole
    # mission is one share, like any other program, rather than one share per component.
    assert all(os.getpgid(pid) == pid for pid in pids)
    assert {os.getsid(pid) for pid in pids} == {os.getsid(process.pid)}
    interrupt(process)
    log, _ = process.communicate(timeout=60)
    assert process.returncode == 128 + signal.SIGINT, log
    assert (
        log.index("Stopping executor executor")
        < log.index("Stopping skillset slam")
        < log.index("Stopping driver bag_player")
    )
    assert not [pid for pid in pids if alive(pid)]
    assert run_records(run_env)[0]["state"] == "finished"


def test_a_crashing_skillset_is_reported_and_ends_the_run(
    start_run: StartRun, run_env: dict[str, str], example_copy: Callable[..., Path], tmp_path: Path
) -> None:
    example = example_copy(rate=0.2)
    process = start_run(example, tmp_path / "out")
    wait_for(lambda: tree_running(run_env), timeout=120, message="the mission to be running")
    slam = next(c for c in run_records(run_env)[0]["components"] if c["name"] == "slam")
    pids = component_pids(run_env)
    os.kill(slam["pid"], signal.SIGSEGV)  # the skillset process dies as a native crash would kill it
    log, _ = process.communicate(timeout=60)
    assert process.returncode == 3, log
    assert f"Skillset slam exited unexpectedly with code {-signal.SIGSEGV}" in log
    assert not [pid for pid in pids if alive(pid)]
    record = run_records(run_env)[0]
    assert next(c for c in record["components"] if c["name"] == "slam")["state"] == "failed"


def test_a_detached_run_is_listed_logged_and_stopped_by_handle(
    spawned: Spawn, run_env: dict[str, str], example_copy: Callable[..., Path], tmp_path: Path
) -> None:
    example = example_copy(rate=0.2)
    started = subprocess.run(
        coral(
            "run",
            str(example),
            "--detach",
            "--handle",
            "mission-a",
            "--group",
            "lab",
            "--output",
            str(tmp_path / "out"),
        ),
        env=run_env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert started.returncode == 0, started.stderr
    assert started.stdout.strip() == "mission-a"
    try:
        wait_for(lambda: tree_running(run_env), timeout=120, message="the detached mission to be running")
        listing = subprocess.run(coral("ps"), env=run_env, capture_output=True, text=True, timeout=60).stdout
        assert "mission-a" in listing and "lab" in listing and "slam(s):ready" in listing
        logs = subprocess.run(
            coral("logs", "mission-a", "slam"), env=run_env, capture_output=True, text=True, timeout=60
        ).stdout
        assert "slam | Component slam ready" in logs
        pids = component_pids(run_env) + [run_records(run_env)[0]["supervisor_pid"]]
        stopped = subprocess.run(
            coral("stop", "--group", "lab"), env=run_env, capture_output=True, text=True, timeout=90
        )
        assert stopped.returncode == 0 and "mission-a: stopped" in stopped.stdout
        assert not [pid for pid in pids if alive(pid)]
        assert (
            "no running instances"
            in subprocess.run(coral("ps"), env=run_env, capture_output=True, text=True, timeout=60).stdout
        )
        assert (
            json.loads((Path(run_env["CORAL_STATE_DIR"]) / "runs/mission-a/run.json").read_text())[
                "exit_code"
            ]
            == 128 + signal.SIGINT
        )
    finally:
        for record in run_records(run_env):
            if alive(record["supervisor_pid"]):
                os.kill(record["supervisor_pid"], signal.SIGKILL)
            for component in record["components"]:
                if component.get("pid") and alive(component["pid"]):
                    os.killpg(component["pid"], signal.SIGKILL)


def test_coral_stop_ends_the_components_of_a_supervisor_that_was_killed(
    spawned: Spawn, run_env: dict[str, str], example_copy: Callable[..., Path], tmp_path: Path
) -> None:
    example = example_copy(rate=0.2)
    process = spawned(
        coral("run", str(example), "--handle", "orphaned", "--output", str(tmp_path / "out"), "--no-live"),
        env=run_env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    wait_for(lambda: tree_running(run_env), timeout=120, message="the mission to be running")
    pids = component_pids(run_env)
    process.kill()  # the supervisor dies without a chance to stop anything
    process.wait(timeout=30)
    assert all(alive(pid) for pid in pids)
    stopped = subprocess.run(
        coral("stop", "--handle", "orphaned"), env=run_env, capture_output=True, text=True, timeout=60
    )
    assert stopped.returncode == 0, stopped.stderr
    assert "left by a dead supervisor" in stopped.stdout
    wait_for(
        lambda: not [pid for pid in pids if alive(pid)], timeout=30, message="the orphaned components to end"
    )
