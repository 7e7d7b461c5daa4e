"""Fixtures for mission tests on real robots: the short bag, a `MissionView` of the test's
namespace, and a bounded wait for every robot's tree to end."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from coral.lidar import generating
from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.missions import MissionView, following
from coral_testbed.missions.stack import operator_policy


def real_robot_marks(*, timeout_s: int) -> list[pytest.MarkDecorator]:
    """The marks of a mission test on real robots: it needs the cluster, ROS and the robots, and is
    slow, within `timeout_s`."""
    return [
        pytest.mark.cluster,
        pytest.mark.slow,
        pytest.mark.ros,
        pytest.mark.real_robots,
        pytest.mark.timeout(timeout_s),
    ]


# Short bags keep the tests quick on a shared 2-core machine; the demo plays the full 300 scans.
TEST_SCANS = 40


@pytest.fixture(scope="session")
def short_bag() -> Path:
    """The synthetic dataset (bag + ground truth) of TEST_SCANS scans, generated once and cached."""
    return generating.cached_dataset(generating.BagParams(scans=TEST_SCANS))


@pytest.fixture
def helm_policy(namespace: str) -> dict[str, tuple[str, ...]]:
    """The missions' policy: the host network, and the bags (and the site share) as host paths."""
    return operator_policy(namespace)


@pytest.fixture
def mission(cluster: Cluster, namespace: str) -> MissionView:
    """The test's namespace as a mission sees it: apply, CoralInstances, files on the robots."""
    return MissionView(cluster, namespace)


def wait_finished(
    view: MissionView, robots: list[str], timeout: float, operator_log: Callable[[], str]
) -> dict[str, dict]:
    """Every robot's CoralInstance once its tree ended; on timeout the error has each robot's line,
    the operator's log and the executors' logs."""
    try:
        items = following.follow(
            view.instances, lambda instances: following.finished(instances, robots), timeout=timeout
        )
    except TimeoutError as error:
        logs = "\n".join(f"--- {r} executor:\n{view.log_tail(r, 'executor')}" for r in robots)
        raise AssertionError(f"{error}\n--- operator:\n{operator_log()[-3000:]}\n{logs}") from error
    return {following.robot(i): i for i in items}


def first_real_robot(fleet: realrobots.RealRobots) -> str:
    """The first of the session's real robots (not the operator's node)."""
    from fixtures.robots import REAL_ROBOTS

    return REAL_ROBOTS[0] if REAL_ROBOTS[0] in fleet.names() else sorted(fleet.names())[0]
