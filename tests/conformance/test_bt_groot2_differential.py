"""Acceptance 1 of issue 49: real BT.CPP's Groot2Publisher (behaviortreepy, BT.CPP 4.8.2) and
coral_core.bt's publisher, read through one pyzmq client, give the same FULLTREE (parsed as a tree),
STATUS after every tick, blackboards, recorded transitions and hook behaviour, for the
conformance corpus and random trees.

The suite runs a fixed sample (CORAL_GROOT2_DIFF_TREES random trees, default 150, about 15 s);
`PYTHONPATH=tests python tests/conformance/bt_groot2_differential.py 2000` (in `make bench-bt`) runs more.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from bt_corpus import CORPUS, read_sources, stubbed_copy
from bt_groot2_differential import Report, compare, random_requests
from bt_groot2_engines import LoadRequest
from bt_groot2_hooks import HookReport, HookScript, compare_hooks, random_script
from coral_core.bt.groot2 import protocol as p

TREES = int(os.environ.get("CORAL_GROOT2_DIFF_TREES", "150"))
HOOKED_TREES = int(os.environ.get("CORAL_GROOT2_HOOKED_TREES", "15"))
STUBS = {"leaf_ids": ("StubLeaf",), "cond_ids": (), "deco_ids": ("StubDecorator",)}
# Corpus files that load differently in the two engines (test_bt_corpus_differential.py says why).
CORPUS_SKIP = {"btcpp_v3/extracted/t06_subtree_port_remapping_v3.xml"}
WALL_CLOCK = re.compile(r"<(Sleep|Delay|Timeout)\b")

# Leaves: L1 runs two ticks, L2 fails once then succeeds, Cond alternates.
FIXED = (
    '<root BTCPP_format="4" main_tree_to_execute="Main">'
    '<BehaviorTree ID="Main"><Sequence name="top">'
    '<Fallback name="fb"><Cond name="c1"/><Leaf name="L2"/></Fallback>'
    '<SubTree ID="Sub" name="inner" x="{v}"/>'
    '<Repeat num_cycles="2"><Leaf name="L1"/></Repeat>'
    "</Sequence></BehaviorTree>"
    '<BehaviorTree ID="Sub"><Sequence><Script code="x := x + 1"/><Leaf name="L3"/></Sequence></BehaviorTree>'
    "</root>"
)
FIXED_OUTCOMES = {"L1": [1, 2], "L2": [3, 2], "c1": [3, 2], "L3": [2]}


def fixed(heartbeat_ms: int = 5000) -> LoadRequest:
    return LoadRequest(FIXED, FIXED_OUTCOMES, host_vars={"v": 1}, heartbeat_ms=heartbeat_ms)


@pytest.fixture(scope="module")
def stubbed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    dest = tmp_path_factory.mktemp("corpus")
    return dest, stubbed_copy(dest)


@pytest.mark.skipif(not CORPUS.is_dir(), reason=f"corpus folder {CORPUS} is absent")
def test_corpus_files_read_the_same_through_groot2(stubbed: tuple) -> None:
    dest, entries = stubbed
    requests = {
        rel: LoadRequest("", {}, file=str(dest / rel), main_tree=entry.main_tree, **STUBS)
        for rel, entry in sorted(entries.items())
        if rel not in CORPUS_SKIP
    }
    # A Sleep, Delay or Timeout ends on the wall clock, which the two runs do not share: such
    # files are compared on their first tick only (no wall-clock node can end within it).
    timed = {rel for rel in requests if WALL_CLOCK.search((dest / rel).read_text(encoding="utf-8"))}
    report = compare([(r, q) for r, q in requests.items() if r not in timed], Report(), ticks=20)
    report = compare([(r, q) for r, q in requests.items() if r in timed], report, ticks=1)
    assert not report.mismatches, "\n".join(report.mismatches[:3])
    assert report.trees == len(read_sources()) - len(CORPUS_SKIP)
    assert report.trees - report.rejected >= 20, "most corpus files must load and be compared"


@pytest.mark.slow
def test_random_trees_read_the_same_through_groot2() -> None:
    report = compare(random_requests(range(TREES)), Report())
    assert not report.mismatches, f"{len(report.mismatches)} differ:\n" + "\n".join(report.mismatches[:3])
    assert report.agreeing == TREES
    assert report.rejected >= TREES // 40 and report.tick_errors >= TREES // 40


@pytest.mark.slow
def test_hooks_on_random_trees_behave_as_in_bt_cpp() -> None:
    cases = [
        (label, request, lambda uids, seed=i: random_script(seed, uids))
        for i, (label, request) in enumerate(random_requests(range(HOOKED_TREES), broken_share=0))
    ]
    report = compare_hooks(cases, HookReport())
    assert not report.mismatches, "\n".join(report.mismatches[:3])
    assert report.runs >= HOOKED_TREES - 2 and report.held >= 3, "breakpoints must be reached and unlocked"


@pytest.mark.parametrize("status", ["SUCCESS", "FAILURE", "SKIPPED"])
@pytest.mark.parametrize("remove", [False, True])
def test_a_breakpoint_unlocked_with_a_status_acts_as_in_bt_cpp(status: str, remove: bool) -> None:
    # uid 4 is L2 (the Fallback's second child), uid 7 the leaf inside the SubTree.
    hooks = [p.HookRecord(uid=4), p.HookRecord(uid=7)]
    report = compare_hooks([("fixed", fixed(), HookScript(hooks, [(status, remove)], ticks=5))], HookReport())
    assert not report.mismatches, "\n".join(report.mismatches)
    assert report.held >= 2


@pytest.mark.parametrize("forced", [2, 3, 4])
@pytest.mark.parametrize("once", [False, True])
def test_a_replace_hook_acts_as_in_bt_cpp(forced: int, once: bool) -> None:
    hooks = [
        p.HookRecord(uid=3, mode=p.REPLACE, desired_status=forced, once=once),
        p.HookRecord(uid=9, mode=p.REPLACE, desired_status=5 - forced if forced < 4 else 4, once=once),
    ]
    report = compare_hooks([("fixed", fixed(), HookScript(hooks, ticks=5))], HookReport())
    assert not report.mismatches, "\n".join(report.mismatches)


def test_a_silent_client_loses_its_breakpoints_after_the_heartbeat_delay_as_in_bt_cpp() -> None:
    script = HookScript([p.HookRecord(uid=4), p.HookRecord(uid=7)], ticks=3, silent_heartbeat=True)
    # A second, not less: BT.CPP's heartbeat thread must wake within it after the client's requests.
    report = compare_hooks([("fixed", fixed(heartbeat_ms=1000), script)], HookReport())
    assert not report.mismatches, "\n".join(report.mismatches)
