"""What the mission tests on real robots share: the short bag's length, a bounded wait for every
robot's tree to end, and the session's first real robot. The kind tests use the first two too."""

from __future__ import annotations

from collections.abc import Callable

from coral_testbed.cluster import realrobots
from coral_testbed.missions import MissionView, following

# Short bags keep the tests quick on a shared 2-core machine; the demo plays the full 300 scans.
TEST_SCANS = 40


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
