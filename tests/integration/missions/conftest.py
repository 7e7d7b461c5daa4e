"""What the mission tests on kind robots share: the short bag's length and a bounded wait for every
robot's tree to end."""

from __future__ import annotations

from collections.abc import Callable

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
