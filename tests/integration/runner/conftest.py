"""Fixtures for robot-runner tests: a runner over fresh robots that leaves nothing behind."""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.runner import RobotRunner, network

StartRunner = Callable[..., RobotRunner]


@pytest.fixture
def robot_names() -> Callable[..., list[str]]:
    """Unique robot names (`r1` -> `r1-<hex>`), so tests never touch the session's kwok robots."""
    suffix = uuid.uuid4().hex[:6]
    return lambda *short: [f"{name}-{suffix}" for name in short]


@pytest.fixture
def start_runner(cluster: Cluster, tmp_path: Path) -> Iterator[StartRunner]:
    """Starts a `RobotRunner` over the given robots; at teardown stops it, deletes its Nodes and
    checks that no process, namespace or link of its slot survived."""
    runners: list[RobotRunner] = []

    def start(robots: list[str], **options: object) -> RobotRunner:
        runner = RobotRunner(cluster.api_client, robots, root=tmp_path / f"robots-{len(runners)}", **options)
        runners.append(runner)
        runner.start()
        return runner

    yield start
    for runner in runners:
        slot = runner.network.slot if runner.network else None
        runner.stop(remove_nodes=True)
        if slot is not None:
            assert not network.marked_pids(slot), "robot-runner processes survived stop"
            assert not network.slot_resources(slot), "robot-runner namespaces or links survived stop"
