"""A skillset process signals readiness, then shuts down cleanly on SIGINT and SIGTERM."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import pytest
from coral.plugins import manifest as manifests
from fixtures.processes import Spawn

from .runtime_processes import PYTHON, finish, start_skillset

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_skillset_is_ready_after_export_and_clears_readiness_on_a_signal(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn, signum: signal.Signals
) -> None:
    plugins = tmp_path / "plugins"
    log = tmp_path / "skillset.log"
    process = start_skillset(spawned, ros_env, plugins, log, name="lab_examples")
    folder = plugins / "lab_examples"
    manifest = manifests.read_manifest(folder)
    assert (manifest.component.name, manifest.component.node_name) == ("lab_examples", "lab_examples")
    assert "Component lab_examples ready" in log.read_text()
    process.send_signal(signum)
    assert finish(process, 30, log) == 0, log.read_text()
    assert not (folder / "ready").exists()
    assert "Component lab_examples stopping" in log.read_text()
    assert manifests.read_manifest(folder).behaviors, "the export stays for executors that loaded it"


def _main_thread_wakeups(pid: int) -> int:
    """How many times the process's main thread has gone to sleep and woken up again so far."""
    for line in Path(f"/proc/{pid}/task/{pid}/status").read_text().splitlines():
        if line.startswith("voluntary_ctxt_switches:"):
            return int(line.split()[1])
    raise AssertionError(f"no context switch count for process {pid}")


def test_an_idle_skillset_main_thread_sleeps_until_it_is_stopped(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    # A main thread that looks at a flag ten times a second takes a core from a busy component's
    # work each time; it must sleep until a signal or a stop request, and still stop at once.
    log = tmp_path / "skillset.log"
    process = start_skillset(spawned, ros_env, tmp_path / "plugins", log, name="lab_examples")
    quiet_window_s = 0.5
    deadline = time.monotonic() + 10.0
    before = _main_thread_wakeups(process.pid)
    idle = False
    while not idle and time.monotonic() < deadline:
        time.sleep(quiet_window_s)  # the window measured, not a wait for an event
        after = _main_thread_wakeups(process.pid)
        idle, before = after == before, after
    assert idle, f"the main thread kept waking: {before} wake-ups within 10 s of being ready"
    process.send_signal(signal.SIGTERM)
    assert finish(process, 30, log) == 0, log.read_text()
    assert "Component lab_examples stopping" in log.read_text()


def test_a_namespace_ros_refuses_is_bad_input_not_a_crash(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    log = tmp_path / "skillset.log"
    plugins = str(tmp_path / "plugins")
    process = spawned(
        [PYTHON, "-m", "coral_skillsets.examples", "--plugins", plugins, "--namespace", "lab//a"],
        env=ros_env,
        stdout=log.open("w"),
        stderr=subprocess.STDOUT,
    )
    assert finish(process, 60, log) == 2, log.read_text()
    assert "error: Invalid namespace: namespace must not contain repeated '/'" in log.read_text()
    assert "Traceback" not in log.read_text()
