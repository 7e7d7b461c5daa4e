"""Fixtures shared by every test folder; each lives in its own module under tests/fixtures/.

`make test` runs the suite in two lanes (`pytest -n 2`, pytest-xdist): the kind folder, whose tests
share one kind cluster and run one after another on it, and everything else. Each lane keeps its
tests in collection order, so package and module fixtures are made once, in one process. The lanes
share only what is built to be shared between parallel runs: DDS domains claimed by lock,
registries and control planes on free ports, the project's dockerd (kept running while any kind
cluster uses it). Tests marked `quiet` measure speed against a reference within a few percent,
which a busy neighbour lane would swamp: `make test` runs them after the lanes, alone.
"""

from __future__ import annotations

from typing import Any

import pytest

pytest_plugins = [
    "fixtures.ros",
    "fixtures.processes",
    "fixtures.operator",
    "fixtures.cluster",
    "fixtures.images",
    "fixtures.prometheus",
]

KIND_LANE_PREFIX = "tests/integration/kind/"


def lane_of(nodeid: str) -> str:
    """The lane a test (by its node id, relative to the repository) runs in under `make test`."""
    return "kind" if nodeid.startswith(KIND_LANE_PREFIX) else "suite"


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    # xdist's scope scheduler hands each scope to one worker whole; the lanes are the scopes.
    from xdist.scheduler import LoadScopeScheduling

    class LaneScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return lane_of(nodeid)

    return LaneScheduling(config, log)


_ENGINE_RUNNING_AT_START = pytest.StashKey[bool]()


def _is_controller(config: pytest.Config) -> bool:
    # Under xdist the lanes are workers; the session's start and end belong to the process above them.
    return not hasattr(config, "workerinput")


def pytest_configure(config: pytest.Config) -> None:
    if _is_controller(config):
        from coral_testbed.kind import engine

        config.stash[_ENGINE_RUNNING_AT_START] = engine.project_engine_running()


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session: pytest.Session) -> None:
    """Fails the run when it leaves the project's dockerd running with no kind cluster on it: each
    lane stops it after its own cluster only if no other cluster is left, so a dockerd running now
    is one no run will stop (a dockerd that ran before the session is left alone)."""
    config = session.config
    if not _is_controller(config) or config.stash.get(_ENGINE_RUNNING_AT_START, True):
        return
    from coral_testbed.kind import clusters, engine

    if not engine.project_engine_running():
        return
    node_engine = engine.project_engine()
    if node_engine.is_serving() and clusters.runs_a_cluster(node_engine):
        return
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write("\n")  # xdist's progress line does not end with one
        reporter.write_line(
            "the project's dockerd started by this run is still running with no kind cluster on it "
            "(`coral dev-cluster down` stops it)",
            red=True,
        )
    session.exitstatus = pytest.ExitCode.TESTS_FAILED
