"""`coral logs SYSTEM -f` on the three kind robots: every robot's components followed live through
the API server, each line prefixed robot/component, plain text in a pipe, every container's lines
in the order it printed them, and Ctrl-C (SIGINT) ends it cleanly.

Issue 53, acceptance 4.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
from coral_testbed.images import catalog
from coral_testbed.kind import faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from missions import realsystems as rs

from .fleet import ROBOTS, fleet_system, pull_for, stops_on_sigterm

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1800)]

SYSTEM = "chatty"
# A driver that counts, five lines a second, so order and gaps are visible in what `coral logs` prints.
COUNTER = 'i=0; while true; do i=$((i+1)); echo "count $i"; sleep 0.2; done'
LINES_PER_ROBOT = 25
FOLLOWED_FOR_S = 3.0
TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sleep msec="600000"/>
  </BehaviorTree>
</root>
"""
PREFIX = re.compile(r"^(?P<robot>[a-z0-9-]+)/(?P<component>[a-z0-9-]+) *\| (?P<line>.*)$")


class Followed:
    """`coral logs` run as a user runs it, its stdout a pipe; lines kept with when they arrived."""

    def __init__(self, args: list[str], env: dict[str, str]) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "coral", "logs", *args],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.lines: list[tuple[float, str]] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append((time.monotonic(), line.rstrip("\n")))

    def counts(self) -> dict[str, list[tuple[float, int]]]:
        """Robot -> (arrival, n) of every `count n` line of its counter, in the order printed."""
        found: dict[str, list[tuple[float, int]]] = {}
        for arrived, line in list(self.lines):
            match = PREFIX.match(line)
            if match and match["component"] == "counter" and match["line"].startswith("count "):
                found.setdefault(match["robot"], []).append((arrived, int(match["line"].split()[1])))
        return found

    def interrupt(self) -> tuple[int, str]:
        """Ctrl-C, as a terminal sends it: SIGINT, then the exit code and stderr."""
        self.process.send_signal(signal.SIGINT)
        _, stderr = self.process.communicate(timeout=20)
        self.reader.join(timeout=10)
        return self.process.returncode, stderr


def test_coral_logs_follows_three_robots_live_in_order_and_stops_cleanly_on_ctrl_c(
    kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    robots = sorted(ROBOTS)
    namespace = kind_operator.namespace
    nodes = sorted(faults.node_of(kind_operator.running, robot) for robot in robots)
    counter = {
        "name": "counter",
        "image": catalog.by_name()["examples-skillset"].reference,
        "command": ["sh", "-c", stops_on_sigterm(COUNTER)],
    }
    manifest = fleet_system(SYSTEM, int(ros_env["ROS_DOMAIN_ID"]), TREE, drivers=[counter])
    pull_for(kind_operator, robots, manifest)
    rs.create(kind_operator.custom, namespace, manifest)

    def running_pods() -> list[str]:
        listed = rs.pods(kind_operator.core, namespace, SYSTEM)
        return sorted(p.spec.node_name for p in listed if p.status.phase == "Running")

    wait_for(
        lambda: running_pods() == sorted(nodes * 2),
        timeout=300,
        interval=1,
        message=lambda: f"a counter and an executor running on every robot: {running_pods()}",
    )

    env = {**os.environ, "KUBECONFIG": str(kind_operator.cluster.kubeconfig)}
    env.pop("CORAL_STATE_DIR", None)
    followed = Followed([SYSTEM, "-n", namespace, "-f"], env)

    def followed_live(robot: str) -> bool:
        # Lines kept coming for a while, not one batch of what the log held when it was read.
        counted = followed.counts().get(robot, [])
        return len(counted) >= LINES_PER_ROBOT and counted[-1][0] - counted[0][0] >= FOLLOWED_FOR_S

    try:
        wait_for(
            lambda: all(followed_live(r) for r in robots),
            timeout=120,
            interval=0.2,
            message=lambda: f"every robot's counter followed live: {followed.lines[-20:]}",
        )
    finally:
        code, stderr = followed.interrupt()
    spans = {r: round(c[-1][0] - c[0][0], 1) for r, c in followed.counts().items()}
    print(
        f"followed {len(followed.lines)} lines of {len(robots)} robots, counters live for {spans} s;"
        f" exit {code} on SIGINT"
    )
    assert code in (0, 130), f"exit {code}: {stderr}"
    assert "Traceback" not in stderr and "Aborted" not in stderr, stderr

    lines = [line for _, line in followed.lines]
    assert not [line for line in lines if "\x1b" in line], "no colour codes in a pipe"
    unprefixed = [line for line in lines if not PREFIX.match(line)]
    assert not unprefixed, unprefixed[:5]
    seen = {(m["robot"], m["component"]) for m in map(PREFIX.match, lines) if m}
    assert seen >= {(r, c) for r in robots for c in ("counter", "executor")}, seen
    for robot, counted in followed.counts().items():
        numbers = [n for _, n in counted]
        # In order and none lost: the counter's own sequence, from its first line.
        assert numbers == list(range(numbers[0], numbers[0] + len(numbers))), (robot, numbers)

    # One robot's one component, without -f: what its log holds, and it ends by itself.
    one = subprocess.run(
        [
            sys.executable,
            "-m",
            "coral",
            "logs",
            SYSTEM,
            "-n",
            namespace,
            "--robot",
            robots[0],
            "-c",
            "counter",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert one.returncode == 0, one.stderr
    prefixes = {m["robot"] + "/" + m["component"] for m in map(PREFIX.match, one.stdout.splitlines()) if m}
    assert prefixes == {f"{robots[0]}/counter"}, one.stdout[-500:]
