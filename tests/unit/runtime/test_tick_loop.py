"""The executor's tick loop: wake-ups tick at once, a tree that signals its wake-ups is not polled,
booked deadlines tick it, a stop halts the running behavior, records flow."""

from __future__ import annotations

import threading
import time

import pytest
from coral.executor.ticking import TickLoop
from coral.executor.wakeups import WakeSchedule
from coral_core.bt import Status
from coral_core.bt.leaves import StatefulAction
from coral_testbed.waiting import wait_for

from .tree_fakes import Collect, FailsAtOnce, Refused, build_loop, start

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


def _loop(xml: str, collect: Collect, rate_hz: float) -> TickLoop:
    behaviors = [Work, Forever, Waits, Deadline, WokenWithinItsTick, FailsFirstRun, FailsAtOnce, Refused]
    return build_loop(xml, collect, {b.__name__: b for b in behaviors}, rate_hz=rate_hz)


def _run_in_background(loop: TickLoop, stop: threading.Event) -> tuple[threading.Event, list[int]]:
    """Runs `loop` on a thread until `stop` (a SIGTERM gives 143); the event is set once it returned,
    with its exit code in the list."""
    finished = threading.Event()
    codes: list[int] = []

    def run() -> None:
        codes.append(loop.run(stop, lambda: 143))
        finished.set()

    threading.Thread(target=run, daemon=True).start()
    return finished, codes


def test_wake_ups_never_tick_the_tree_faster_than_its_rate() -> None:
    """Issue 50: a retry of a behavior that fails at once wakes the tree from its own tick; a robot
    whose skillset lost its state ticked 400 times a second with its rate set to 20."""
    collect = Collect()
    loop = _loop(
        '<root BTCPP_format="4"><BehaviorTree ID="M">'
        '<RetryUntilSuccessful num_attempts="-1"><FailsAtOnce/></RetryUntilSuccessful>'
        "</BehaviorTree></root>",
        collect,
        rate_hz=20.0,
    )
    stop = threading.Event()
    started = time.monotonic()
    finished = start(loop, stop)
    try:
        wait_for(lambda: loop.tree.tick_count >= 21, timeout=10, interval=0.01, message="21 ticks")
        took = time.monotonic() - started
    finally:
        stop.set()
        loop.tree.wake_up()
    assert finished.wait(5.0)
    # 21 ticks are 20 periods at the least, however many wake-ups asked for more.
    assert took >= 20 / 20.0 - 0.01, f"{loop.tree.tick_count} ticks in {took:.2f} s at 20 Hz"
    counted = [(r["ts"], r["tick_count"]) for r in collect.records if r["event"] == "status"]
    (t0, n0), (t1, n1) = counted[0], counted[-1]
    assert n1 - n0 <= (t1 - t0) * 20.0 + 1, "the executor's own counter agrees"


def test_a_stop_halts_the_running_behavior_and_reports_halted() -> None:
    HALTED.clear()
    collect = Collect()
    loop = _loop(
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Forever/></BehaviorTree></root>', collect, 50.0
    )
    stop = threading.Event()
    finished, codes = _run_in_background(loop, stop)
    wait_for(
        lambda: any(r["event"] == "transition" and r["status"] == "RUNNING" for r in list(collect.records)),
        timeout=5,
        interval=0.01,
        message="Forever to start",
    )
    stop.set()
    loop.tree.wake_up()
    assert finished.wait(5.0)
    assert codes == [143]
    assert len(HALTED) == 1
    assert collect.records[-1] == {
        **collect.records[-1],
        "event": "finished",
        "root_status": "HALTED",
        "exit_code": 143,
    }


class Waits(Forever):
    """RUNNING until a wake-up that never comes; keeps BT.CPP's wake-up contract."""

    SIGNALS_WAKE_UP = True


class Deadline(StatefulAction):
    """Books a tick 0.1 s ahead with the executor and succeeds on the first tick after it."""

    SIGNALS_WAKE_UP = True

    def on_start(self) -> Status:
        self.due = time.monotonic() + 0.1
        self.context.wake_at(self.due)
        return Status.RUNNING

    def on_running(self) -> Status:
        return Status.SUCCESS if time.monotonic() >= self.due else Status.RUNNING


def test_a_tree_whose_running_nodes_signal_wake_ups_is_not_polled_at_the_tick_rate() -> None:
    polled = _loop(
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Forever/></BehaviorTree></root>', Collect(), 100.0
    )
    waiting = _loop(
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Sequence><Waits/></Sequence></BehaviorTree></root>',
        Collect(),
        100.0,
    )
    stop = threading.Event()
    done = [start(polled, stop), start(waiting, stop)]
    try:
        wait_for(lambda: polled.tree.tick_count >= 20, timeout=10, message="the polled tree to tick 20 times")
        assert polled.tree.needs_polling() and not waiting.tree.needs_polling()
        # Over the same time, the tree waiting for a wake-up ticked once (its first tick) or
        # twice (the status heartbeat, once a second).
        assert waiting.tree.tick_count <= 2
    finally:
        stop.set()
        for loop in (polled, waiting):
            loop.tree.wake_up()
    assert all(event.wait(5.0) for event in done)


def _polling_answers(loop: TickLoop) -> list[bool]:
    """Every answer the loop gets from `needs_polling`: all False means only wake-ups ticked the tree."""
    answers: list[bool] = []
    asked = loop.tree.needs_polling
    loop.tree.needs_polling = lambda: answers.append(asked()) or answers[-1]
    return answers


def _booking_loop(xml: str) -> tuple[TickLoop, list[bool]]:
    """A loop of `xml` whose nodes book their wake-up times in a schedule of its own, and the answers
    it gets from `needs_polling`."""
    loop = _loop(xml, Collect(), 10.0)
    schedule = WakeSchedule()
    loop.context.wakeups = schedule
    loop.context.wake_at = schedule.add
    return loop, _polling_answers(loop)


def test_a_booked_deadline_ticks_the_tree_although_nothing_wakes_it() -> None:
    loop, polled = _booking_loop(
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Deadline/></BehaviorTree></root>'
    )
    stop = threading.Event()
    # The tree is never polled and nothing wakes it: only the booked time can end it before the
    # status heartbeat (1 s) ticks it.
    started = time.monotonic()
    finished = start(loop, stop)
    if not finished.wait(5.0):
        stop.set()
        loop.tree.wake_up()
        raise AssertionError("the booked deadline did not tick the tree")
    assert loop.tree.last_status == Status.SUCCESS
    assert time.monotonic() - started < 0.75 and not any(polled)


def test_the_wake_schedule_returns_the_earliest_live_booking_and_consumes_due_ones() -> None:
    schedule = WakeSchedule()
    late, early = schedule.add(20.0), schedule.add(10.0)
    assert schedule.next_due(now=0.0) == 10.0
    schedule.cancel(early)
    assert schedule.next_due(now=0.0) == 20.0
    assert schedule.next_due(now=25.0) == 20.0  # due: returned once, so the caller ticks now
    assert schedule.next_due(now=25.0) is None
    schedule.cancel(late)  # cancelling a consumed booking is harmless


class WokenWithinItsTick(StatefulAction):
    """Its event arrives while the tree is still ticking, before the loop starts to wait."""

    SIGNALS_WAKE_UP = True

    def on_start(self) -> Status:
        self.wake_up()
        return Status.RUNNING

    def on_running(self) -> Status:
        return Status.SUCCESS


class FailsFirstRun(StatefulAction):
    """FAILURE at once on its first run (its parent then returns RUNNING), SUCCESS on the next."""

    SIGNALS_WAKE_UP = True
    RUNS = [0]

    def on_start(self) -> Status:
        self.RUNS[0] += 1
        return Status.FAILURE if self.RUNS[0] == 1 else Status.SUCCESS

    def on_running(self) -> Status:
        return Status.SUCCESS


# Each tree can only progress through one kind of wake-up. While every running node signals its
# wake-ups the loop does not poll (asserted: it ticks only on wake-ups, at most at its 10 Hz), and
# ticks anyway once a second (the status heartbeat): a missed wake-up shows as a second or more.
WAKE_UP_KINDS = {
    "a timer (Sleep)": ('<Sleep msec="50"/>', Status.SUCCESS),
    "a timer that halts a child (Timeout)": ('<Timeout msec="50"><Waits/></Timeout>', Status.FAILURE),
    "a timer before a child (Delay)": ('<Delay delay_msec="50"><AlwaysSuccess/></Delay>', Status.SUCCESS),
    "a booked deadline": ("<Deadline/>", Status.SUCCESS),
    "an event within the tick": ("<WokenWithinItsTick/>", Status.SUCCESS),
    "a repeat after a child succeeded": ('<Repeat num_cycles="2"><AlwaysSuccess/></Repeat>', Status.SUCCESS),
    "a retry after a child failed": (
        '<RetryUntilSuccessful num_attempts="2"><FailsFirstRun/></RetryUntilSuccessful>',
        Status.SUCCESS,
    ),
}


@pytest.mark.parametrize("kind", list(WAKE_UP_KINDS))
def test_each_kind_of_wake_up_ticks_the_tree_without_waiting_for_the_heartbeat(kind: str) -> None:
    body, expected = WAKE_UP_KINDS[kind]
    FailsFirstRun.RUNS[0] = 0
    loop, polled = _booking_loop(f'<root BTCPP_format="4"><BehaviorTree ID="M">{body}</BehaviorTree></root>')
    stop = threading.Event()
    started = time.monotonic()
    finished = start(loop, stop)
    ended = finished.wait(5.0)
    took = time.monotonic() - started
    stop.set()
    loop.tree.wake_up()
    assert ended and loop.tree.last_status == expected
    assert took < 0.75, f"{kind}: the tree ended after {took:.2f} s, as if a wake-up was missed"
    assert not any(polled), f"{kind}: the tree was polled, so its wake-ups went untested"


def test_the_failure_that_says_why_is_reported_over_a_condition_that_said_no_first() -> None:
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M">'
        "<Fallback><AlwaysFailure/><Refused/></Fallback>"
        "</BehaviorTree></root>"
    )
    loop = _loop(xml, Collect(), 50.0)
    assert loop.run(threading.Event(), lambda: 143) != 0
    assert loop.last_failure is not None
    assert "Refused" in loop.last_failure["path"], loop.last_failure
    assert loop.last_failure["message"] == "skillset slam is unavailable: it restarted"
