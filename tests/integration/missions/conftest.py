"""Fixtures for mission tests: a `MissionStack` (operator + robot runner) per test, left clean."""

from __future__ import annotations

import shutil
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from coral.lidar import generating
from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.missions import MissionStack, following
from coral_testbed.runner import network

StartStack = Callable[[list[str]], MissionStack]
# Short bags keep the tests quick on a shared 2-core machine; the demo plays the full 300 scans.
TEST_SCANS = 40


@pytest.fixture
def suffix() -> str:
    """Makes robot names unique: robots created in a session stay for the session."""
    return uuid.uuid4().hex[:6]


@pytest.fixture(scope="session")
def short_bag() -> Path:
    """The synthetic dataset (bag + ground truth) of TEST_SCANS scans, generated once and cached."""
    return generating.cached_dataset(generating.BagParams(scans=TEST_SCANS))


@pytest.fixture
def start_stack(cluster: Cluster, namespace: str, tmp_path: Path) -> Iterator[StartStack]:
    """Starts the operator and a robot runner for the test's namespace; at teardown stops them and
    checks that no robot process, namespace or link of the runner's slot survived."""
    stacks: list[MissionStack] = []

    def start(robots: list[str]) -> MissionStack:
        stack = MissionStack(cluster, namespace, robots, tmp_path / f"stack-{len(stacks)}")
        stacks.append(stack)
        stack.start()
        return stack

    yield start
    for stack in stacks:
        runner = stack.runner
        slot = runner.network.slot if runner is not None and runner.network is not None else None
        stack.stop()
        if slot is not None:
            assert not network.marked_pids(slot), "robot processes survived the stop"
            assert not network.slot_resources(slot), "robot namespaces or links survived the stop"


def wait_finished(stack: MissionStack, robots: list[str], timeout: float) -> dict[str, dict]:
    """Every robot's CoralInstance once its tree ended; on timeout the error has each robot's line,
    the operator's log and the executors' logs."""
    try:
        items = following.follow(
            stack.instances,
            lambda instances: following.finished(instances, robots),
            timeout=timeout,
            check=stack.check_operator,
        )
    except TimeoutError as error:
        logs = "\n".join(f"--- {r} executor:\n{stack.log_tail(r, 'executor')}" for r in robots)
        raise AssertionError(f"{error}\n--- operator:\n{stack.operator_log_tail()}\n{logs}") from error
    return {following.robot(i): i for i in items}


def place_bag_on_real_robot(fleet: realrobots.RealRobots, robot: str, bag: Path, robot_path: str) -> None:
    """Copies the bag folder into the real robot's `robot_path` (a link would point outside the
    robot's mount view, where its containers cannot follow it)."""
    target = fleet.host_path(robot, robot_path)
    if target.exists():
        shutil.rmtree(target)
    shutil.copytree(bag, target)


def first_real_robot(fleet: realrobots.RealRobots) -> str:
    """The first of the session's real robots (not the operator's node)."""
    from fixtures.robots import REAL_ROBOTS

    return REAL_ROBOTS[0] if REAL_ROBOTS[0] in fleet.names() else sorted(fleet.names())[0]
