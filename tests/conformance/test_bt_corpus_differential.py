"""Every corpus file, with generic port-less stubs, gets the same load verdict and the same root status
over 200 tickExactlyOnce calls in real BT.CPP (behaviortreepy) and in coral_core.bt, except the differences
listed in KNOWN with their reason."""

from __future__ import annotations

from pathlib import Path

import coral_core.bt as bt
import pytest
from bt_corpus import CORPUS, read_sources, stubbed_copy
from bt_harness import Outcomes, run_btcpp, run_coral, stub_registry

pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason=f"corpus folder {CORPUS} is absent")

# file -> (BT.CPP 4.8 verdict, coral verdict, why they differ)
KNOWN = {
    "btcpp_v3/extracted/t06_subtree_port_remapping_v3.xml": (
        "REJECT",
        "LOADED",
        "leniency: v3 SequenceStar is loaded as SequenceWithMemory with a warning",
    ),
}
STUBS = {"leaf_ids": ("StubLeaf",), "cond_ids": (), "deco_ids": ("StubDecorator",)}


@pytest.fixture(scope="module")
def stubbed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    dest = tmp_path_factory.mktemp("corpus")
    return dest, stubbed_copy(dest)


@pytest.mark.parametrize("rel", sorted(e.path for e in read_sources()) if CORPUS.is_dir() else [])
def test_corpus_file_gives_the_same_verdict_and_root_statuses_as_bt_cpp(rel: str, stubbed: tuple) -> None:
    dest, entries = stubbed
    entry = entries[rel]
    path = str(dest / rel)
    theirs = run_btcpp(
        None, Outcomes({}), 200, file=path, main_tree=entry.main_tree, log_transitions=False, **STUBS
    )
    outcomes = Outcomes({})
    registry = stub_registry(outcomes, **STUBS)
    ours = run_coral(None, outcomes, 200, file=path, main_tree=entry.main_tree, registry=registry)
    if rel in KNOWN:
        their_verdict, our_verdict, _why = KNOWN[rel]
        assert (theirs.verdict, ours.verdict) == (their_verdict, our_verdict)
        return
    assert ours.verdict == theirs.verdict, (theirs.error, ours.error)
    assert ours.statuses == theirs.statuses
    if ours.verdict == "REJECT":
        assert ours.error and (":" in ours.error), "a rejection names the file and line"


def test_t09_scripting_with_its_enums_registered_succeeds_like_bt_cpp_4_10(stubbed: tuple) -> None:
    dest, _entries = stubbed
    registry = stub_registry(Outcomes({}), **STUBS)
    for name, value in {"THE_ANSWER": 42, "RED": 1, "BLUE": 2, "GREEN": 3}.items():
        registry.register_enum(name, value)
    tree = bt.build_tree(bt.load_tree_file(dest / "btcpp/extracted/t09_scripting.xml", registry), registry)
    assert tree.tick_exactly_once() == bt.Status.SUCCESS
    assert tree.root_blackboard.get("A") == 42


def test_t16_runs_once_the_host_sets_the_global_value(stubbed: tuple) -> None:
    dest, entries = stubbed
    registry = stub_registry(Outcomes({}), **STUBS)
    path = dest / "btcpp/extracted/t16_global_blackboard.xml"
    doc = bt.load_tree_file(path, registry, main_tree="MainTree")
    tree = bt.build_tree(doc, registry, blackboard={"value": 3})
    assert tree.tick_exactly_once() == bt.Status.SUCCESS
    assert tree.root_blackboard.get("value_sqr") == 9


def test_moveit_pro_tree_ids_with_spaces_are_accepted_with_a_warning(stubbed: tuple) -> None:
    dest, _entries = stubbed
    registry = stub_registry(Outcomes({}), **STUBS)
    doc = bt.load_tree_file(dest / "moveit_pro/lab_sim_plan_to_pose.xml", registry)
    assert any("contains spaces" in w for w in doc.warnings)
    assert bt.build_tree(doc, registry).tick_exactly_once() == bt.Status.SUCCESS


# Where the 4.10 oracle in SOURCES.md ran a differently stubbed file: its MoveBase stub kept the
# `goal="{target}"` port, which declares the caller's `move_goal` through the SubTree remap. The
# port-less stub here declares nothing, so `move_goal='1;2;3'` (`=`, not `:=`) finds no entry, in
# BT.CPP 4.8 on this same copy too (the other test compares the two engines on it).
STUBBED_DIFFERENTLY_410 = {"btcpp/extracted/t06_subtree_port_remapping.xml": "TICKERR"}
# Where our verdict differs from the BT.CPP 4.10 oracle recorded in SOURCES.md, and why.
LENIENT_VS_410 = {
    "moveit_pro/lab_sim_plan_to_pose.xml": "tree IDs with spaces are accepted (4.9+ name validation rejects)",
    "btcpp_v3/extracted/t06_subtree_port_remapping_v3.xml": "v3 SequenceStar loaded as SequenceWithMemory",
}


@pytest.mark.parametrize("rel", sorted(e.path for e in read_sources()) if CORPUS.is_dir() else [])
def test_corpus_verdict_matches_bt_cpp_4_10_or_a_listed_leniency(rel: str, stubbed: tuple) -> None:
    dest, entries = stubbed
    entry = entries[rel]
    outcomes = Outcomes({})
    registry = stub_registry(outcomes, **STUBS)
    if rel == "btcpp/extracted/t09_scripting.xml":
        for name, value in {"THE_ANSWER": 42, "RED": 1, "BLUE": 2, "GREEN": 3}.items():
            registry.register_enum(name, value)
    ours = run_coral(None, outcomes, 200, file=str(dest / rel), main_tree=entry.main_tree, registry=registry)
    if rel in LENIENT_VS_410:
        assert (entry.oracle_410, ours.verdict) == ("REJECT", "LOADED")
    elif rel in STUBBED_DIFFERENTLY_410:
        assert (entry.oracle_410, ours.verdict) == ("LOADED", STUBBED_DIFFERENTLY_410[rel]), ours.error
    else:
        assert ours.verdict == entry.oracle_410, ours.error
