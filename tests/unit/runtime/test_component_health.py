"""Heartbeat bookkeeping behind `LibraryDegraded` and fail-fast calls, with an injected clock."""

from __future__ import annotations

from coral.executor.health import HealthMonitor
from coral.sdk import topics


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _beat(component: str, state: str = "alive") -> topics.Heartbeat:
    return topics.Heartbeat(component, "skillset", state, 1234)


def test_a_never_seen_component_is_not_degraded() -> None:
    monitor = HealthMonitor(FakeClock(), timeout_s=1.5)
    assert monitor.failure("examples") is None


def test_a_silent_component_is_degraded_after_the_timeout_and_recovers_on_a_beat() -> None:
    clock = FakeClock()
    monitor = HealthMonitor(clock, timeout_s=1.5)
    monitor.observe(_beat("examples"))
    clock.now += 1.4
    assert monitor.degraded(["examples"]) == {}
    clock.now += 0.2
    assert monitor.degraded(["examples"]) == {"examples": "no heartbeat for over 1.5 s"}
    monitor.observe(_beat("examples"))
    assert monitor.failure("examples") is None


def test_the_reason_stays_the_same_while_the_silence_grows() -> None:
    """So `LibraryDegraded` is written once when a component goes, not once per tick after."""
    clock = FakeClock()
    monitor = HealthMonitor(clock, timeout_s=1.5)
    monitor.observe(_beat("examples"))
    reasons = set()
    for _ in range(50):
        clock.now += 0.1
        reasons.add(monitor.failure("examples"))
    assert reasons == {None, "no heartbeat for over 1.5 s"}


def test_a_stopping_component_is_degraded_at_once() -> None:
    monitor = HealthMonitor(FakeClock(), timeout_s=1.5)
    monitor.observe(_beat("examples", "stopping"))
    assert monitor.failure("examples") == "it shut down"


def test_heartbeats_survive_the_wire_and_garbage_is_ignored() -> None:
    beat = _beat("examples")
    assert topics.Heartbeat.decode(beat.encode()) == beat
    assert topics.Heartbeat.decode("not json") is None
    assert topics.CancelRequest.decode('{"service": "/a"}') is None


def test_the_next_failure_is_when_the_earliest_live_component_would_turn_silent() -> None:
    clock = FakeClock()
    monitor = HealthMonitor(clock, timeout_s=1.5)
    assert monitor.next_failure_at(["slam"]) is None  # never seen: nothing to wake up for
    monitor.observe(_beat("slam"))
    clock.now += 0.5
    monitor.observe(_beat("snapshot"))
    assert monitor.next_failure_at(["slam", "snapshot"]) == 101.5
    assert monitor.next_failure_at(["snapshot"]) == 102.0
    clock.now += 1.2  # slam is silent now: only snapshot can still turn silent
    assert monitor.next_failure_at(["slam", "snapshot"]) == 102.0
    monitor.observe(_beat("snapshot", "stopping"))
    assert monitor.next_failure_at(["slam", "snapshot"]) is None


def test_a_component_back_as_a_new_process_is_degraded_for_a_while_even_without_silence() -> None:
    clock = FakeClock()
    monitor = HealthMonitor(clock, timeout_s=1.5, restart_s=5.0)
    monitor.observe(topics.Heartbeat("examples", "skillset", "alive", 1, "first"))
    clock.now += 0.4
    # The same pid (a container's pid 1) but another process: a restart quicker than the timeout.
    monitor.observe(topics.Heartbeat("examples", "skillset", "alive", 1, "second"))
    assert monitor.state("examples") == "degraded"
    assert "restarted" in monitor.degraded(["examples"])["examples"]
    clock.now += 4.0
    monitor.observe(topics.Heartbeat("examples", "skillset", "alive", 1, "second"))
    assert monitor.refuse_call("examples") is not None  # the tree is told: a behavior fails
    clock.now += 1.1
    monitor.observe(topics.Heartbeat("examples", "skillset", "alive", 1, "second"))
    assert monitor.state("examples") == "alive"


def test_a_restarted_component_stays_degraded_until_a_call_into_it_has_failed() -> None:
    """Issue 50: the SLAM skillset came back without its state while the tree was busy elsewhere;
    5 s later it read healthy, and the tree's next call found a skillset that had forgotten it."""
    clock = FakeClock()
    monitor = HealthMonitor(clock, timeout_s=1.5, restart_s=5.0)
    monitor.observe(topics.Heartbeat("slam", "skillset", "alive", 1, "first"))
    monitor.observe(topics.Heartbeat("slam", "skillset", "alive", 1, "second"))
    for _ in range(120):  # a minute of beats from the new process, and no call into it
        clock.now += 0.5
        monitor.observe(topics.Heartbeat("slam", "skillset", "alive", 1, "second"))
    assert monitor.degraded(["slam"]) == {"slam": "it restarted (a new process; its state is lost)"}
    assert monitor.failure("slam") is not None, "asking is not telling"
    assert "restarted" in (monitor.refuse_call("slam") or "")
    assert monitor.state("slam") == "alive", "told, and longer ago than restart_s"
    assert monitor.refuse_call("slam") is None, "its next call goes through"


def test_beats_of_one_process_never_count_as_a_restart() -> None:
    clock = FakeClock()
    monitor = HealthMonitor(clock, timeout_s=1.5)
    for _ in range(5):
        monitor.observe(topics.Heartbeat("examples", "skillset", "alive", 1, "only"))
        clock.now += 0.2
    assert monitor.state("examples") == "alive"


def test_a_heartbeat_without_an_instance_still_decodes() -> None:
    old = '{"component":"examples","kind":"skillset","state":"alive","pid":7}'
    assert topics.Heartbeat.decode(old) == topics.Heartbeat("examples", "skillset", "alive", 7, "")
