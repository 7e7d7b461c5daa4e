"""The operator, as its container's first process, stops at once on SIGTERM while it still loads.

The kernel drops a signal whose action is the default for the first process of a PID namespace,
so without a handler of its own the operator ignored a pod deletion that came before kopf set
its handler, and the kubelet killed it only at the end of the grace period (30 s by default) with
the next operator of the chart's `Recreate` waiting behind it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from coral_testbed import pidns
from coral_testbed.waiting import wait_for


def _catches_sigterm(pid: int) -> bool:
    """Whether the process has a handler for SIGTERM (its SigCgt mask in /proc)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigCgt:"):
            return bool(int(line.split()[1], 16) & (1 << (signal.SIGTERM - 1)))
    return False


@pytest.mark.skipif(not pidns.can_make_one(), reason="needs unshare and a new PID namespace")
def test_sigterm_while_the_operator_loads_ends_it_at_once(tmp_path: Path) -> None:
    env = {**os.environ, "KUBECONFIG": str(tmp_path / "no-cluster"), "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("KUBERNETES_SERVICE_HOST", None)
    launcher = pidns.first_process(
        [sys.executable, "-m", "coral_operator"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        operator = wait_for(
            lambda: pidns.first_process_of(launcher),
            timeout=30,
            interval=0.01,
            message="the operator's process",
        )
        # Before its first line of Python no process can catch a signal; from the verb's start on
        # the operator must, long before kopf, the Kubernetes client and the handlers are loaded.
        wait_for(lambda: _catches_sigterm(operator), timeout=30, interval=0.01, message="a SIGTERM handler")
        os.kill(operator, signal.SIGTERM)
        # 128 + SIGTERM is the loading operator's own exit; once kopf runs, its stop ends otherwise.
        output, _ = launcher.communicate(timeout=10)
    finally:
        if launcher.poll() is None:
            launcher.kill()
            launcher.wait()
    assert launcher.returncode == 128 + signal.SIGTERM, output
    assert "Traceback" not in output, output
