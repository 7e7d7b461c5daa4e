"""Seeded random trees about values, run in real BT.CPP (behaviortreepy) and in coral_core.bt, must leave
identical traces:

- scripts (`bt_random_scripts`): every operator on every kind of value, text read as a number, and
  the values a condition accepts as a bool;
- typed ports (`bt_random_ports`): how a port converts an entry that holds another kind, and how
  SetBlackboard parses text into a typed entry.

CORAL_BT_SCRIPT_TREES and CORAL_BT_PORT_TREES set how many trees run (default 2,000 each, about
15 s and 10 s).
"""

from __future__ import annotations

import os

import pytest
from bt_differential import Report, compare_random_ports, compare_random_scripts

SCRIPT_TREES = int(os.environ.get("CORAL_BT_SCRIPT_TREES", "2000"))
PORT_TREES = int(os.environ.get("CORAL_BT_PORT_TREES", "2000"))


def assert_all_agree(report: Report, trees: int) -> None:
    assert not report.mismatches, f"{len(report.mismatches)} of {report.trees} trees differ:\n" + "\n".join(
        report.mismatches[:5]
    )
    assert report.agreeing == trees


@pytest.mark.slow
def test_random_scripts_behave_exactly_as_bt_cpp() -> None:
    report = compare_random_scripts(range(SCRIPT_TREES))
    assert_all_agree(report, SCRIPT_TREES)
    # Most random scripts hit an error somewhere; both outcomes must stay well represented, or the
    # generator has drifted into testing only one of them.
    assert SCRIPT_TREES // 10 <= report.tick_errors <= SCRIPT_TREES - SCRIPT_TREES // 10


@pytest.mark.slow
def test_typed_ports_read_entries_exactly_as_bt_cpp() -> None:
    report = compare_random_ports(range(PORT_TREES))
    assert_all_agree(report, PORT_TREES)
    # Trees that load and run to the end must stay a good share, beside refusals and errors.
    ran = PORT_TREES - report.rejected - report.tick_errors
    assert ran >= PORT_TREES // 5
    assert report.rejected >= PORT_TREES // 10 and report.tick_errors >= PORT_TREES // 10
