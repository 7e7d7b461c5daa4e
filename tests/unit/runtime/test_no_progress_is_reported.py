"""A tree that makes no progress (one node failing the same way again and again) is reported, and a
healthy loop whose conditions say no on every pass is not.

Issue 50: the SLAM skillset came back without its state; the tree retried `ProcessScan` about
240,000 times in ten minutes ("localization is disabled") while its instance read Ready, RUNNING.
"""

from __future__ import annotations

import threading
from typing import Any

import pytest
from coral.executor import kubernetes_sink
from coral.executor.progress import ProgressWatch
from coral.executor.ticking import TickLoop
from coral_core.bt import Status
from coral_core.bt.leaves import StatefulAction
from coral_core.instance_status import CoralInstanceStatus
from coral_testbed.waiting import wait_for

from .tree_fakes import Collect, FailsAtOnce, build_loop

DISABLED = FailsAtOnce.MESSAGE


def _fail(watch: ProgressWatch, at: float, path: str = "Main/ProcessScan", message: str = DISABLED) -> None:
    watch.failed(path, path.rpartition("/")[2], message, now=at, wall=1_000_000.0 + at)


def test_one_node_failing_the_same_way_for_the_limit_is_no_progress() -> None:
    watch = ProgressWatch(limit_s=10.0)
    for second in range(0, 10):
        _fail(watch, float(second))
        assert watch.stuck(float(second)) is None, "a loop shorter than the limit is a retry"
    _fail(watch, 10.0)
    assert watch.stuck(10.0) == {
        "path": "Main/ProcessScan",
        "node_id": "ProcessScan",
        "message": DISABLED,
        "since": 1_000_000.0,
    }


def test_counts_in_the_message_do_not_make_it_another_failure() -> None:
    watch = ProgressWatch(limit_s=2.0)
    for attempt in range(5):
        _fail(watch, float(attempt), message=f"scan {1200 + attempt} rejected after {attempt}.5 s")
    stuck = watch.stuck(4.0)
    assert stuck is not None and stuck["message"] == "scan 1200 rejected after 0.5 s", "the first message"


@pytest.mark.parametrize(
    "between",
    ["the failing node succeeds", "another node fails another way", "the failures stop for the limit"],
)
def test_the_loop_ends_when(between: str) -> None:
    watch = ProgressWatch(limit_s=5.0)
    for second in range(0, 6):
        _fail(watch, float(second))
    assert watch.stuck(5.0) is not None
    if between == "the failing node succeeds":
        watch.succeeded("Main/ProcessScan")
    elif between == "another node fails another way":
        _fail(watch, 5.5, path="Main/SaveMap", message="disk full")
    else:
        assert watch.stuck(10.0) is not None
        assert watch.stuck(10.1) is None
        return
    assert watch.stuck(5.5) is None


def test_failures_without_a_message_and_a_zero_limit_are_never_no_progress() -> None:
    silent, never = ProgressWatch(limit_s=1.0), ProgressWatch(limit_s=0.0)
    for tenth in range(100):
        _fail(silent, tenth / 10, message="")
        _fail(never, tenth / 10)
    assert silent.stuck(10.0) is None and never.stuck(10.0) is None


class Works(StatefulAction):
    """Succeeds at once, as a `ProcessScan` handed a scan does."""

    SIGNALS_WAKE_UP = True

    def on_start(self) -> Status:
        return Status.SUCCESS

    def on_running(self) -> Status:
        return Status.SUCCESS


def _reported(records: Collect) -> list[Any]:
    """The `no_progress` of every status record so far."""
    return [r.get("no_progress") for r in list(records.records) if r["event"] == "status"]


def _run(body: str, records: Collect, limit_s: float) -> tuple[TickLoop, threading.Event, threading.Event]:
    xml = f'<root BTCPP_format="4"><BehaviorTree ID="M">{body}</BehaviorTree></root>'
    behaviors = {"FailsAtOnce": FailsAtOnce, "Works": Works}
    loop = build_loop(xml, records, behaviors, rate_hz=50.0, no_progress_s=limit_s)
    stop, finished = threading.Event(), threading.Event()

    def run() -> None:
        loop.run(stop, lambda: 143)
        finished.set()

    threading.Thread(target=run, daemon=True).start()
    return loop, stop, finished


def _stop(loop: TickLoop, stop: threading.Event, finished: threading.Event) -> None:
    stop.set()
    loop.tree.wake_up()
    assert finished.wait(5.0)


def test_the_executor_reports_a_retry_loop_that_makes_no_progress_and_its_sink_writes_it() -> None:
    records = Collect()
    loop, stop, finished = _run(
        '<RetryUntilSuccessful num_attempts="-1"><FailsAtOnce/></RetryUntilSuccessful>', records, 0.5
    )
    try:
        stuck = wait_for(
            lambda: next((r for r in _reported(records) if r), None), timeout=10, message="no progress"
        )
    finally:
        _stop(loop, stop, finished)
    assert "FailsAtOnce" in stuck["path"] and stuck["message"] == DISABLED
    state = CoralInstanceStatus()
    written = []
    for record in records.records:
        state = kubernetes_sink.summarize(state, record)
        written.append((state.to_patch().get("tree") or {}).get("noProgress", "absent"))
    assert written[0] == "absent", "nothing to say while the loop is young"
    assert any(
        w and w != "absent" and w["path"] == stuck["path"] and w["message"] == DISABLED for w in written
    )


def test_the_sink_clears_the_report_when_the_loop_ends() -> None:
    loop = {
        "event": "status",
        "root_status": "RUNNING",
        "no_progress": {"path": "M/A", "message": "m", "since": 0.0},
    }
    state = kubernetes_sink.summarize(CoralInstanceStatus(), loop)
    reported = state.to_patch()["tree"]["noProgress"]
    assert reported == {"path": "M/A", "message": "m", "since": "1970-01-01T00:00:00Z"}
    state = kubernetes_sink.summarize(state, {**loop, "no_progress": None})
    assert state.to_patch()["tree"]["noProgress"] is None, "a merge patch's null clears the field"


def test_a_healthy_loop_whose_conditions_say_no_each_pass_makes_progress() -> None:
    """The SLAM mission's shape: a condition fails without a message on every pass (no stop was
    requested), and the work succeeds."""
    records = Collect()
    loop, stop, finished = _run(
        '<RetryUntilSuccessful num_attempts="-1"><Fallback><AlwaysFailure/>'
        "<ForceFailure><Works/></ForceFailure></Fallback></RetryUntilSuccessful>",
        records,
        0.2,
    )
    try:
        wait_for(lambda: loop.tree.tick_count >= 40, timeout=10, message="40 passes of the loop")
    finally:
        _stop(loop, stop, finished)
    assert not any(_reported(records)), "reported no progress in a loop that works"
