"""What the operator keeps per object goes with the object, and a burst of deletions ends in one trim.

Issue 47: the operator grew 2.85 MB per robot and did not give it back after the system was
deleted. The integration test (tests/integration/operator/test_hostile_memory.py) measures the
process; these check the bookkeeping that makes it possible.
"""

from __future__ import annotations

import threading

from coral_operator.reconcile.memory import Memory
from coral_operator.reconcile.trimming import Trimmer


def test_a_deleted_systems_status_and_history_are_forgotten() -> None:
    memory = Memory()
    memory.statuses.remember("uid-1", "7", {"conditions": []})
    memory.histories.remember(("ns", "s", "uid-1"), [])
    memory.creates.expect("uid-1", ["s-r1"])
    memory.forget_system("uid-1", "ns", "s")
    assert memory.statuses.last("uid-1")[0] is None
    assert memory.creates.in_flight("uid-1", {}) == (set(), set())
    assert len(memory.histories) == 0


def test_a_deleted_instances_writes_and_derived_pods_are_forgotten() -> None:
    memory = Memory()
    memory.statuses.remember("uid-1", "7", {"conditions": []})
    memory.pacing.wrote("uid-1", deferred=True)
    memory.desired_pods.get("uid-1", 1, lambda: [{"metadata": {"name": "s-r1-slam"}}])
    memory.creates.expect("uid-1", ["s-r1-slam"])
    memory.vetted.add("uid-1", 1, "uid-s")
    memory.forget_instance("uid-1", "ns", "s-r1")
    assert memory.statuses.last("uid-1")[0] is None
    assert memory.pacing.deferred_writes("uid-1") == 0
    assert memory.desired_pods.get("uid-1", 1, list) == [], "built again"
    assert memory.creates.in_flight("uid-1", {}) == (set(), set())
    assert not memory.vetted.has("uid-1", 1, "uid-s")


def test_a_burst_of_deletions_ends_in_one_trim() -> None:
    trimmed = threading.Event()
    calls: list[int] = []

    def trim() -> None:
        calls.append(1)
        trimmed.set()

    trimmer = Trimmer(delay=0.05, trim=trim)
    for _ in range(100):
        trimmer.soon()
    assert trimmed.wait(timeout=5)
    assert calls == [1]
    trimmer.soon()
    trimmer.stop()
    assert calls == [1]


def test_the_real_trim_runs_where_glibc_is() -> None:
    trimmer = Trimmer(delay=0.0)
    trimmer._run()
    assert trimmer.runs == 1
