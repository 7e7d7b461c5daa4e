"""Seeded random scripts run in real BT.CPP (behaviortreepy) and in coral.bt must leave identical
traces: every operator on every kind of value, text read as a number, and the values a condition
accepts as a bool (`bt_random_scripts`).

CORAL_BT_SCRIPT_TREES sets how many trees run (default 2,000, about 20 s).
"""

from __future__ import annotations

import os

import pytest
from bt_differential import compare_random_scripts

TREES = int(os.environ.get("CORAL_BT_SCRIPT_TREES", "2000"))


@pytest.mark.slow
def test_random_scripts_behave_exactly_as_bt_cpp() -> None:
    report = compare_random_scripts(range(TREES))
    assert not report.mismatches, f"{len(report.mismatches)} of {report.trees} trees differ:\n" + "\n".join(
        report.mismatches[:5]
    )
    assert report.agreeing == TREES
    # Most random scripts hit an error somewhere; both outcomes must stay well represented, or the
    # generator has drifted into testing only one of them.
    assert TREES // 10 <= report.tick_errors <= TREES - TREES // 10
