"""Runs seeded random trees in real BT.CPP (behaviortreepy) and in coral_core.bt and compares their whole
traces: per tick the root status (a runtime error counts as a status), the leaf calls with the
blackboard each leaf sees, the root blackboard's values as `std::to_string` prints them, the node
transitions as BT.CPP's FileLogger records them; then haltTree() with its halts and final board,
and a few ticks after it.

Used by test_bt_random_differential.py; `python tests/conformance/bt_differential.py N` runs N trees.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import bt_random_ports
import bt_random_scripts
from bt_harness import TRACE_FIELDS, Outcomes, Run, finish_batch, run_btcpp, run_coral
from bt_random_trees import VARS, generate

TICKS = 15
BATCH = 100
BROKEN_SHARE = 0.08


@dataclass
class Report:
    trees: int = 0
    agreeing: int = 0
    rejected: int = 0
    tick_errors: int = 0
    used: set[str] = field(default_factory=set)
    broken_kinds: set[str] = field(default_factory=set)
    mismatches: list[str] = field(default_factory=list)
    seconds: float = 0.0


@dataclass
class Case:
    """One tree to run in both engines."""

    seed: int
    xml: str
    outcomes: dict[str, list[int]]
    mode: str
    host: dict[str, object]
    ticks: int


def compare(cases: Iterable[Case], report: Report) -> Report:
    """Runs every case in both engines (BT.CPP's file loggers settle a batch at a time)."""
    start = time.monotonic()
    pending: list = []
    pairs: list = []

    def settle() -> None:
        finish_batch(pending)
        for case, theirs, ours in pairs:
            report.trees += 1
            if ours.trace() == theirs.trace():
                report.agreeing += 1
                report.rejected += theirs.verdict == "REJECT"
                report.tick_errors += theirs.verdict == "TICKERR"
            else:
                report.mismatches.append(describe(case, theirs, ours))
        pairs.clear()

    for case in cases:
        theirs = run_btcpp(
            case.xml,
            Outcomes(case.outcomes),
            case.ticks,
            mode=case.mode,
            host_vars=case.host,
            batch=pending,
            observe=True,
        )
        ours = run_coral(
            case.xml, Outcomes(case.outcomes), case.ticks, mode=case.mode, host_vars=case.host, observe=True
        )
        pairs.append((case, theirs, ours))
        if len(pending) >= BATCH:
            settle()
    settle()
    report.seconds = time.monotonic() - start
    return report


def compare_random_trees(seeds: range, ticks: int = TICKS, broken_share: float = BROKEN_SHARE) -> Report:
    report = Report()

    def cases() -> Iterator[Case]:
        for seed in seeds:
            gen = generate(seed, broken_share=broken_share)
            report.used |= gen.used
            if gen.broken:
                report.broken_kinds.add(gen.broken)
            yield Case(seed, gen.xml, gen.outcomes, gen.mode, VARS, ticks)

    return compare(cases(), report)


def compare_random_scripts(seeds: range, ticks: int = 2) -> Report:
    """The trees of `bt_random_scripts`: scripts on every kind of value, two ticks each."""
    host = bt_random_scripts.VARS
    cases = (Case(seed, bt_random_scripts.generate(seed), {}, "exactly_once", host, ticks) for seed in seeds)
    return compare(cases, Report())


def compare_random_ports(seeds: range, ticks: int = 3) -> Report:
    """The trees of `bt_random_ports`: typed ports reading entries of every kind."""
    host = bt_random_ports.HOST
    cases = (Case(seed, bt_random_ports.generate(seed), {}, "exactly_once", host, ticks) for seed in seeds)
    return compare(cases, Report())


def describe(case: Case, theirs: Run, ours: Run) -> str:
    traces = zip(TRACE_FIELDS, theirs.trace(), ours.trace(), strict=True)
    first = next(n for n, x, y in traces if x != y)
    return (
        f"seed {case.seed} ({case.mode}) differs in {first}: BT.CPP {theirs.verdict} {theirs.statuses} "
        f"{theirs.error[:100]!r} vs coral {ours.verdict} {ours.statuses} {ours.error[:100]!r}\n"
        f"  {case.xml[:600]}"
    )


def main() -> None:
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 5000
    first = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    report = compare_random_trees(range(first, first + count))
    for line in report.mismatches[:20]:
        print(line)
    print(
        f"{report.agreeing} of {report.trees} random trees agree with BT.CPP "
        f"({report.rejected} refused by both, {report.tick_errors} ending in the same runtime error) "
        f"in {report.seconds:.0f} s"
    )


if __name__ == "__main__":
    main()
