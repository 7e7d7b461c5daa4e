"""`coral dev-cluster` as a user runs it: up, status, robots, down, demo; and nothing left running after.

These start control planes of their own (not the session's), in temporary folders.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from coral_testbed.cluster import binaries, controlplane, processes

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

CORAL = [sys.executable, "-m", "coral", "dev-cluster", "local"]


@pytest.fixture(autouse=True)
def _needs_binaries() -> None:
    # Against an external cluster the pinned binaries are optional; locally they are required.
    if os.environ.get("KUBECONFIG") and binaries.optional_bin_dir() is None:
        pytest.skip("the local control plane's binaries are not built")


def _coral(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CORAL, *args], capture_output=True, text=True, timeout=timeout, check=False)


def _kubectl(kubeconfig: Path, *args: str) -> str:
    kubectl = str(binaries.find_bin_dir() / "kubectl")
    env = {**os.environ, "KUBECONFIG": str(kubeconfig)}
    return subprocess.run(
        [kubectl, *args], capture_output=True, text=True, env=env, check=True, timeout=60
    ).stdout


def _processes_mentioning(text: str) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and entry.name != str(os.getpid()):
            try:
                if text.encode() in (entry / "cmdline").read_bytes():
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


def _status_rows(stdout: str) -> list[list[str]]:
    """The rows of `coral dev-cluster local status`'s table (COMPONENT, PID, HEALTH, LOG), split on blanks."""
    lines = stdout.splitlines()
    header = next(i for i, line in enumerate(lines) if line.split()[:2] == ["COMPONENT", "PID"])
    footer = ([], ["server"], ["kubeconfig"])
    return [line.split() for line in lines[header + 1 :] if line.split()[:1] not in footer]


def test_up_robots_status_and_down_leave_no_process_behind(tmp_path: Path) -> None:
    state_dir = tmp_path / "dev"
    up = _coral(
        "up",
        "--dir",
        str(state_dir),
        "--kwok-robots",
        "2",
        "--kwok-prefix",
        "robot-",
        "--label",
        "coral.dev/model=tb4",
    )
    assert up.returncode == 0, up.stderr
    recorded = controlplane.load_state(state_dir)
    assert recorded is not None
    try:
        kubeconfig = Path(up.stdout.strip())
        assert kubeconfig == state_dir.resolve() / "kubeconfig" and kubeconfig.is_file()
        assert "Starting kube-apiserver" in up.stderr

        status = _coral("status", "--dir", str(state_dir))
        assert status.returncode == 0, status.stdout + status.stderr
        assert str(kubeconfig) in status.stdout
        rows = _status_rows(status.stdout)
        assert {"etcd", "kube-apiserver", "kube-controller-manager", "kube-scheduler", "kwok"} == {
            row[0] for row in rows
        }
        assert {row[2] for row in rows} == {"healthy"} and "\x1b" not in status.stdout

        nodes = _kubectl(kubeconfig, "get", "nodes", "-L", "coral.dev/robot,coral.dev/model", "--no-headers")
        rows = sorted(line.split() for line in nodes.splitlines())
        assert [(r[0], r[1], r[-2], r[-1]) for r in rows] == [
            ("robot-1", "Ready", "robot-1", "tb4"),
            ("robot-2", "Ready", "robot-2", "tb4"),
        ]

        assert _coral("robots", "ready", "robot-2", "--not-ready", "--dir", str(state_dir)).returncode == 0
        assert _kubectl(kubeconfig, "get", "node", "robot-2", "--no-headers").split()[1] == "NotReady"
        assert _coral("robots", "ready", "robot-2", "--dir", str(state_dir)).returncode == 0
        assert _kubectl(kubeconfig, "get", "node", "robot-2", "--no-headers").split()[1] == "Ready"

        again = _coral("up", "--dir", str(state_dir))
        assert again.returncode == 0 and again.stdout.strip() == str(kubeconfig)
        assert "already running" in again.stderr
    finally:
        down = _coral("down", "--dir", str(state_dir))
    assert down.returncode == 0, down.stderr
    assert "Stopped 5 processes" in down.stderr
    assert not [p.name for p in recorded.processes if processes.is_alive(p)]
    assert _processes_mentioning(str(state_dir.resolve())) == []
    assert _coral("status", "--dir", str(state_dir)).returncode == 1


def test_demo_shows_a_pod_running_on_a_robot_and_stops_everything() -> None:
    demo = _coral("demo")
    assert demo.returncode == 0, demo.stdout + demo.stderr
    out = demo.stdout
    assert "$ kubectl get nodes -L coral.dev/robot,coral.dev/model" in out
    assert "turtlebot4" in out and "spot" in out
    pod_line = next(line for line in out.splitlines() if line.startswith("hello-robot"))
    assert "Running" in pod_line.split() and "robot-3" in pod_line.split()
    assert "Stopped 5 control-plane processes" in out
    folder = next(line.split(" in ")[-1] for line in out.splitlines() if "Preparing certificates" in line)
    assert _processes_mentioning(folder.strip()) == []


def test_a_failing_component_is_reported_with_its_log_and_the_rest_is_stopped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from coral_testbed.cluster import components

    real = components.build_apiserver
    monkeypatch.setattr(components, "build_apiserver", lambda layout: [*real(layout), "--no-such-flag"])

    with pytest.raises(controlplane.ControlPlaneError) as failure:
        controlplane.start(tmp_path / "broken")
    assert "kube-apiserver exited during start-up" in str(failure.value)
    assert "unknown flag: --no-such-flag" in str(failure.value)
    assert _processes_mentioning(str((tmp_path / "broken").resolve())) == []
