"""Seeded random trees run in real BT.CPP (behaviortreepy) and in coral_core.bt must leave identical traces:
per tick the root status (a runtime error counts, located by its script and cause), the leaf calls
with the blackboard each leaf sees, the root blackboard's values, the node transitions as BT.CPP's
FileLogger records them; then haltTree() and three ticks that must start the tree over. A share of
the trees is broken on purpose.

CORAL_BT_DIFF_TREES sets how many trees run (default 2,000, about 30 s); the benchmark
`python tests/conformance/bt_differential.py 10000` runs more.
"""

from __future__ import annotations

import os

import pytest
from bt_differential import compare_random_trees
from bt_harness import bundled_btcpp_version
from bt_random_trees import BROKEN, CONTROLS, DECORATORS

TREES = int(os.environ.get("CORAL_BT_DIFF_TREES", "2000"))
# What the trees must reach, so that a generator change cannot quietly drop a feature.
FEATURES = {
    "Script",
    "ScriptCondition",
    "SetBlackboard",
    "UnsetBlackboard",
    "WasEntryUpdated",
    "Leaf",
    "Cond",
}


def test_the_oracle_is_the_bt_cpp_release_the_tests_were_written_for() -> None:
    # behaviortreepy 0.1.4 bundles 4.8.2: it knows SkipUnlessUpdated (4.6) but not TryCatch (4.9).
    assert bundled_btcpp_version() == "4.8.2"


@pytest.mark.slow
def test_random_trees_behave_exactly_as_bt_cpp() -> None:
    report = compare_random_trees(range(TREES))
    assert not report.mismatches, f"{len(report.mismatches)} of {report.trees} trees differ:\n" + "\n".join(
        report.mismatches[:5]
    )
    assert report.agreeing == TREES
    assert set(CONTROLS) | set(DECORATORS) | FEATURES <= report.used, "the generator lost a node type"
    assert report.broken_kinds == set(BROKEN), "the generator lost a kind of broken tree"
    # Both engines must be exercised on all three outcomes, not only on trees that run cleanly.
    assert report.rejected >= TREES // 25 and report.tick_errors >= TREES // 25
