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
    memory.remember_status("uid-1", "7", {"conditions": []})
    memory.remember_revisions(("ns", "s", "uid-1"), [])
    memory.expect_instances("uid-1", ["s-r1"])
    memory.forget_system("uid-1", "ns", "s")
    assert memory.status_written("uid-1")[0] is None
    assert memory.deferred_writes("uid-1") == 0
    assert memory.instances_in_flight("uid-1", set()) == set()
    assert not memory._history


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
