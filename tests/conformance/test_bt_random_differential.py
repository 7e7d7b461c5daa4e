"""2,000 seeded random trees run in real BT.CPP (behaviortreepy) and in coral.bt must give identical
per-tick root statuses and identical per-node transition streams (as BT.CPP's FileLogger records them)."""

from __future__ import annotations

import pytest
from bt_harness import Outcomes, bundled_btcpp_version, finish_batch, run_btcpp, run_coral
from bt_random_trees import CONTROLS, DECORATORS, VARS, generate

TREES = 2000
TICKS = 15
BATCH = 100


def test_the_oracle_is_the_bt_cpp_release_the_tests_were_written_for() -> None:
    # behaviortreepy 0.1.4 bundles 4.8.2: it knows SkipUnlessUpdated (4.6) but not TryCatch (4.9).
    assert bundled_btcpp_version() == "4.8.2"


@pytest.mark.slow
def test_random_trees_behave_exactly_as_bt_cpp() -> None:
    mismatches: list[str] = []
    used: set[str] = set()
    pending: list = []
    pairs = []

    def compare() -> None:
        finish_batch(pending)
        for seed, gen, theirs, ours in pairs:
            if (theirs.verdict, theirs.statuses, theirs.transitions) != (
                ours.verdict,
                ours.statuses,
                ours.transitions,
            ):
                mismatches.append(
                    f"seed {seed} ({gen.mode}): BT.CPP {theirs.verdict} {theirs.statuses} "
                    f"{theirs.error[:80]} vs coral {ours.verdict} {ours.statuses} "
                    f"{ours.error[:80]}"
                )
        pairs.clear()

    for seed in range(TREES):
        gen = generate(seed)
        used |= gen.used
        theirs = run_btcpp(
            gen.xml, Outcomes(gen.outcomes), TICKS, mode=gen.mode, int_vars=VARS, batch=pending
        )
        ours = run_coral(gen.xml, Outcomes(gen.outcomes), TICKS, mode=gen.mode, int_vars=VARS)
        pairs.append((seed, gen, theirs, ours))
        if len(pending) >= BATCH:
            compare()
    compare()
    assert not mismatches, f"{len(mismatches)} of {TREES} trees differ:\n" + "\n".join(mismatches[:5])
    assert set(CONTROLS) | set(DECORATORS) <= used, "the generator no longer covers every built-in"
