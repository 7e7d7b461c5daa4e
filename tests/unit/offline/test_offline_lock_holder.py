"""The offline copy's lock holder, run as its container's first process: it holds the component's
lock while it runs and lets go of it at once on SIGTERM, so the API server's pods take over when
the kubelet stops the copy rather than after its grace period (30 s by default)."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest
from coral.offline.agent import lock_held
from coral.offline.staticpods import static_copy
from coral_testbed import pidns
from coral_testbed.waiting import wait_for
from offline_pods import CONFIG_MAPS, robot_pods, system

# The lock taken by the holder, and the time within which SIGTERM must free it.
FREED_WITHIN_S = 5.0


@pytest.mark.skipif(not pidns.can_make_one(), reason="needs unshare and a new PID namespace")
def test_the_holder_keeps_the_lock_and_frees_it_at_once_on_sigterm(tmp_path: Path) -> None:
    (pod, *_) = robot_pods(system(offline={"mode": "LastRevision"}))
    copy = static_copy(pod, config_maps=CONFIG_MAPS, files_dir="/f", run_dir="/r")
    holder = copy.pod["spec"]["initContainers"][0]
    lock = tmp_path / "component.lock"
    lock.touch()
    # The holder's own command, its lock path pointed at this test's file.
    command = [*holder["command"][:-1], str(lock)]
    launcher = pidns.first_process(command)
    try:
        first = wait_for(
            lambda: pidns.first_process_of(launcher), timeout=30, interval=0.01, message="its process"
        )
        wait_for(lambda: lock_held(lock), timeout=30, interval=0.05, message="the holder to take the lock")
        # Its handler is set before the lock is taken (the script's first statement).
        subprocess.run(["kill", "-TERM", str(first)], check=True)
        wait_for(
            lambda: not lock_held(lock),
            timeout=FREED_WITHIN_S,
            interval=0.05,
            message="the lock to be free after SIGTERM",
        )
        # A clean stop, not the kubelet's kill at the end of the grace period.
        assert launcher.wait(timeout=FREED_WITHIN_S) == 0
    finally:
        if launcher.poll() is None:
            launcher.send_signal(signal.SIGKILL)
            launcher.wait()
