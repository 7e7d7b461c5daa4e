"""The executor's tick loop: wake-ups tick at once, a stop halts the running behavior, records flow."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace
from typing import Any

from coral.bt import NodeRegistry, Status, load_tree_text
from coral.bt.leaves import StatefulAction
from coral.executor import plugins_phase, sinks
from coral.executor.health import HealthMonitor
from coral.executor.ticking import TickLoop

HALTED: list[str] = []


class Work(StatefulAction):
    """Finishes when a worker thread (standing in for a ROS callback) completes and wakes the tree."""

    DELAY_S = 0.05

    def on_start(self) -> Status:
        self.done = threading.Event()

        def finish() -> None:
            self.done.set()
            self.wake_up()

        if self.DELAY_S >= 0:
            threading.Timer(self.DELAY_S, finish).start()
        return Status.RUNNING

    def on_running(self) -> Status:
        return Status.SUCCESS if self.done.is_set() else Status.RUNNING

    def on_halted(self) -> None:
        HALTED.append(self.path)


class Forever(Work):
    DELAY_S = -1.0


class Collect:
    def __init__(self) -> None:
        self.records: list[dict[str, Any]] = []

    def emit(self, record: dict[str, Any]) -> None:
        self.records.append(record)

    def close(self) -> None:
        pass


def _loop(xml: str, collect: Collect, rate_hz: float) -> TickLoop:
    registry = NodeRegistry.with_builtins()
    registry.register("Work", Work)
    registry.register("Forever", Forever)
    context = SimpleNamespace(health=HealthMonitor(time.monotonic), failure_message=lambda path: "")
    tree = load_tree_text(xml).build(registry, context=context)
    state = plugins_phase.PluginState(used=set(), builtin_ids=set())
    return TickLoop(tree, context, sinks.SinkFanout([collect]), state, rate_hz=rate_hz)


def test_wake_ups_tick_at_once_instead_of_waiting_for_the_period() -> None:
    collect = Collect()
    # At 0.1 Hz a tick waits 10 s; only wake-ups can finish two Works within the 5 s bound below.
    loop = _loop(
        '<root BTCPP_format="4"><BehaviorTree ID="M">'
        "<Sequence><Work/><Work/></Sequence>"
        "</BehaviorTree></root>",
        collect,
        rate_hz=0.1,
    )
    stop = threading.Event()
    finished = threading.Event()
    codes: list[int] = []

    def run() -> None:
        codes.append(loop.run(stop, lambda: 143))
        finished.set()

    threading.Thread(target=run, daemon=True).start()
    if not finished.wait(5.0):
        stop.set()
        loop.tree.wake_up()
        raise AssertionError("the loop waited for its period instead of ticking on wake-ups")
    assert codes == [0]
    assert collect.records[-1]["event"] == "finished" and collect.records[-1]["root"] == "SUCCESS"
    assert collect.records[-2]["event"] == "status" and collect.records[-2]["root"] == "SUCCESS"


def test_a_stop_halts_the_running_behavior_and_reports_halted() -> None:
    HALTED.clear()
    collect = Collect()
    loop = _loop(
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Forever/></BehaviorTree></root>', collect, 50.0
    )
    stop = threading.Event()
    finished = threading.Event()
    codes: list[int] = []

    def run() -> None:
        codes.append(loop.run(stop, lambda: 143))
        finished.set()

    threading.Thread(target=run, daemon=True).start()
    deadline = time.monotonic() + 5
    while not any(r["event"] == "transition" and r["status"] == "RUNNING" for r in list(collect.records)):
        assert time.monotonic() < deadline, "Forever never started"
        time.sleep(0.01)
    stop.set()
    loop.tree.wake_up()
    assert finished.wait(5.0)
    assert codes == [143]
    assert len(HALTED) == 1
    assert collect.records[-1] == {
        **collect.records[-1],
        "event": "finished",
        "root": "HALTED",
        "exit_code": 143,
    }


class Refused(StatefulAction):
    """Fails at once and says why, as a behavior whose skillset is gone does."""

    def on_start(self) -> Status:
        self.context.failures[self.path] = "skillset slam is unavailable: it restarted"
        return Status.FAILURE

    def on_running(self) -> Status:
        return Status.FAILURE


def test_the_failure_that_says_why_is_reported_over_a_condition_that_said_no_first() -> None:
    registry = NodeRegistry.with_builtins()
    registry.register("Refused", Refused)
    failures: dict[str, str] = {}
    context = SimpleNamespace(
        health=HealthMonitor(time.monotonic),
        failures=failures,
        failure_message=lambda path: failures.pop(path, ""),
    )
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M">'
        "<Fallback><AlwaysFailure/><Refused/></Fallback>"
        "</BehaviorTree></root>"
    )
    tree = load_tree_text(xml).build(registry, context=context)
    state = plugins_phase.PluginState(used=set(), builtin_ids=set())
    loop = TickLoop(tree, context, sinks.SinkFanout([Collect()]), state, rate_hz=50.0)
    assert loop.run(threading.Event(), lambda: 143) != 0
    assert loop.last_failure is not None
    assert "Refused" in loop.last_failure["path"], loop.last_failure
    assert loop.last_failure["message"] == "skillset slam is unavailable: it restarted"
