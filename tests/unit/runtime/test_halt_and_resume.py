"""A halt (`spec.halt`) as the executor's tick loop carries it out: every running node halted as
BT.CPP's `haltTree()` halts it, no tick while halted, the park tree ticked to its end (bounded)
after the mission stopped, an acknowledgement in the records, and a resume that starts the tree
again from its beginning."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from typing import Any

from coral.executor.halt_watch import halt_of_instance
from coral.executor.halting import HaltSignal
from coral.executor.kubernetes_sink import summarize
from coral.executor.ticking import TickLoop
from coral_core.bt import Status
from coral_core.bt.leaves import StatefulAction
from coral_core.halt import HaltRequest
from coral_core.instance_status import CoralInstanceStatus
from coral_testbed.waiting import holds_for, wait_for

from .tree_fakes import Collect, build_loop, start


class Logged(StatefulAction):
    """Notes its starts and halts in the executor's context, in order."""

    def on_start(self) -> Status:
        self.context.log.append(("start", self.name))
        return Status.RUNNING

    def on_running(self) -> Status:
        return Status.RUNNING

    def on_halted(self) -> None:
        self.context.log.append(("halt", self.name))


class Mission(Logged):
    """RUNNING until halted, as a navigation does."""


class Park(Logged):
    """Drives to the safe spot: SUCCESS on its third tick."""

    def on_running(self) -> Status:
        self.ticks = getattr(self, "ticks", 0) + 1
        return Status.SUCCESS if self.ticks >= 2 else Status.RUNNING


class Stuck(Logged):
    """A park that never arrives."""


MISSION = """<root BTCPP_format="4">
  <BehaviorTree ID="Main"><Sequence><Mission/></Sequence></BehaviorTree>
  <BehaviorTree ID="GoHome"><Park/></BehaviorTree>
  <BehaviorTree ID="NeverHome"><Stuck/></BehaviorTree>
</root>"""


def _halting_loop(collect: Collect, rate_hz: float = 50.0) -> tuple[TickLoop, HaltSignal]:
    """The tick loop over MISSION with a halt signal that wakes its tree, as the executor wires it."""
    built: list[TickLoop] = []
    halts = HaltSignal(lambda: built[0].tree.wake_up() if built else None)
    loop = build_loop(
        MISSION.replace("<root ", '<root main_tree_to_execute="Main" '),
        collect,
        {"Mission": Mission, "Park": Park, "Stuck": Stuck},
        rate_hz=rate_hz,
        halts=halts,
    )
    built.append(loop)
    loop.context.log = []
    return loop, halts


def _records(collect: Collect, event: str) -> list[dict[str, Any]]:
    return [r for r in list(collect.records) if r["event"] == event]


@contextlib.contextmanager
def _running(
    halted_from_the_start: HaltRequest | None = None,
) -> Iterator[tuple[TickLoop, HaltSignal, Collect]]:
    """The halting loop running on a thread (its signal set first, if asked), stopped on the way out."""
    collect = Collect()
    loop, halts = _halting_loop(collect)
    halts.set(halted_from_the_start)
    stop = threading.Event()
    finished = start(loop, stop)
    try:
        if halted_from_the_start is None:
            wait_for(lambda: loop.context.log, timeout=5, interval=0.01, message="the mission to start")
        yield loop, halts, collect
    finally:
        stop.set()
        loop.tree.wake_up()
        assert finished.wait(5.0), "the loop did not end after the stop"


def test_a_halt_halts_the_running_node_stops_ticking_and_a_resume_starts_the_tree_over() -> None:
    with _running() as (loop, halts, collect):
        assert loop.context.log == [("start", "Mission")]
        asked = time.monotonic()
        halts.set(HaltRequest())
        wait_for(lambda: _records(collect, "halted"), timeout=2, interval=0.01, message="the halt")
        assert time.monotonic() - asked < 1.0, "a halt acts on the next wake-up, not the next tick"
        assert loop.context.log == [("start", "Mission"), ("halt", "Mission")]
        assert all(node.status == Status.IDLE for node in loop.tree.snapshot().nodes), "every status reset"
        status = _records(collect, "status")[-1]
        assert (status["root_status"], status["active_path"]) == ("IDLE", "")
        ticks = loop.tree.tick_count
        holds_for(lambda: loop.tree.tick_count == ticks, 0.5, interval=0.05, message="no tick while halted")

        halts.set(None)
        wait_for(lambda: len(loop.context.log) == 3, timeout=2, interval=0.01, message="a tick again")
        assert loop.context.log[-1] == ("start", "Mission"), "the tree starts again from its beginning"
        assert _records(collect, "resumed")


def test_the_park_tree_runs_to_its_end_after_the_mission_was_halted() -> None:
    with _running() as (loop, halts, collect):
        halts.set(HaltRequest(park_tree="GoHome"))
        (halted,) = wait_for(lambda: _records(collect, "halted"), timeout=2, interval=0.01)
        assert (halted["park_tree"], halted["park_status"]) == ("GoHome", "SUCCESS")
        # The mission stopped before the park tree moved the robot.
        assert loop.context.log == [("start", "Mission"), ("halt", "Mission"), ("start", "Park")]


def test_a_park_tree_that_never_ends_is_halted_when_its_time_is_up() -> None:
    with _running() as (loop, halts, collect):
        asked = time.monotonic()
        halts.set(HaltRequest(park_tree="NeverHome", park_timeout_seconds=1))
        (halted,) = wait_for(lambda: _records(collect, "halted"), timeout=3, interval=0.01)
        took = time.monotonic() - asked
        assert halted["park_status"] == "TIMEOUT"
        assert 1.0 <= took < 1.5, f"the park tree ran {took:.2f} s with 1 s allowed"
        assert loop.context.log[-1] == ("halt", "Stuck")


def test_a_park_tree_the_document_lacks_is_named_and_the_tree_halts_anyway() -> None:
    with _running() as (loop, halts, collect):
        halts.set(HaltRequest(park_tree="Dock"))
        (halted,) = wait_for(lambda: _records(collect, "halted"), timeout=2, interval=0.01)
        assert halted["park_status"] == "MISSING"
        (error,) = _records(collect, "error")
        assert "Dock" in error["message"] and "GoHome" in error["message"]
        assert loop.context.log == [("start", "Mission"), ("halt", "Mission")]


def test_a_robot_halted_before_its_executor_started_never_ticks() -> None:
    with _running(halted_from_the_start=HaltRequest()) as (loop, _halts, collect):
        wait_for(lambda: _records(collect, "halted"), timeout=2, interval=0.01)
        holds_for(lambda: loop.tree.tick_count == 0, 0.3, interval=0.05, message="no tick")
        assert loop.context.log == []
    assert collect.records[-1]["root_status"] == "HALTED", "a stop while halted reads as halted"


def test_the_acknowledgement_lands_on_the_instance_status_and_a_resume_clears_it() -> None:
    acknowledgement = {"event": "halted", "since": 1767268800.0, "park_tree": "GoHome"}
    acknowledgement["park_status"] = "SUCCESS"
    halted = summarize(CoralInstanceStatus(), acknowledgement)
    tree = CoralInstanceStatus.model_validate(halted.to_patch()).tree
    assert tree is not None and tree.halted is not None
    assert (tree.halted.since, tree.halted.park_tree, tree.halted.park_status) == (
        "2026-01-01T12:00:00Z",
        "GoHome",
        "SUCCESS",
    )
    resumed = summarize(halted, {"event": "resumed"})
    # Null in the merge patch: the API server removes the field.
    assert resumed.to_patch()["tree"]["halted"] is None


def test_the_executor_reads_its_halt_from_its_instance_and_halts_on_one_it_cannot_read() -> None:
    assert halt_of_instance({"spec": {"robot": "r1"}}) is None
    asked = halt_of_instance({"spec": {"halt": {"parkTree": "GoHome", "parkTimeoutSeconds": 5}}})
    assert asked == HaltRequest(park_tree="GoHome", park_timeout_seconds=5)
    # Stopping is what was asked, even if the executor is older than the field's new parts.
    assert halt_of_instance({"spec": {"halt": {"parkTimeoutSeconds": "soon"}}}) == HaltRequest()
