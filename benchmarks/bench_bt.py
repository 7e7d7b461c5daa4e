"""Tick time of 100-node all-synchronous trees in coral.bt, stock py_trees (same shape) and BT.CPP
(behaviortreepy); prints BENCH lines including coral's ratio to py_trees against the 0.3 target.

Two trees: one of constant leaves, and a blackboard-heavy one whose every leaf reads or writes an
entry (coral/BT.CPP: Script `k := k + 1` and ScriptCondition `k > 0`; py_trees:
SetBlackboardVariable and CheckBlackboardVariableValue).

Run with `make bench-bt` (or `.venv/bin/python benchmarks/bench_bt.py`).
"""

from __future__ import annotations

import operator
import statistics
import time
from collections.abc import Callable

import behaviortreepy as btpy
import coral.bt as bt
import py_trees

GROUPS = 9
LEAVES = 10  # 1 root + 9 sequences + 90 leaves = 100 nodes
TICKS = 2000
ROUNDS = 5


def tree_xml(board_heavy: bool = False) -> str:
    def leaf(g: int, i: int) -> str:
        if not board_heavy:
            return "<AlwaysSuccess/>"
        if i % 2:
            return f'<ScriptCondition code="k{g} &gt; 0"/>'
        return f'<Script code="k{g} := k{g} + 1"/>'

    groups = "".join(
        "<Sequence>" + "".join(leaf(g, i) for i in range(LEAVES)) + "</Sequence>" for g in range(GROUPS)
    )
    tree = f'<BehaviorTree ID="Main"><Sequence>{groups}</Sequence></BehaviorTree>'
    return f'<root BTCPP_format="4">{tree}</root>'


def host_entries() -> dict[str, int]:
    return {f"k{g}": 0 for g in range(GROUPS)}


def coral_tick(board_heavy: bool = False) -> Callable[[], object]:
    registry = bt.NodeRegistry.with_builtins()
    doc = bt.load_tree_text(tree_xml(board_heavy), registry)
    tree = doc.build(registry, blackboard=host_entries())
    assert len(tree.nodes) == 100
    return tree.tick_exactly_once


def py_trees_tick(board_heavy: bool = False) -> Callable[[], object]:
    py_trees.blackboard.Blackboard.clear()

    def leaf(g: int, i: int) -> py_trees.behaviour.Behaviour:
        if not board_heavy:
            return py_trees.behaviours.Success(f"s{g}_{i}")
        if i % 2:
            check = py_trees.common.ComparisonExpression(f"k{g}", 0, operator.gt)
            return py_trees.behaviours.CheckBlackboardVariableValue(f"c{g}_{i}", check)
        return py_trees.behaviours.SetBlackboardVariable(f"s{g}_{i}", f"k{g}", i + 1, overwrite=True)

    root = py_trees.composites.Sequence("root", memory=True)
    for g in range(GROUPS):
        seq = py_trees.composites.Sequence(f"seq{g}", memory=True)
        seq.add_children([leaf(g, i) for i in range(LEAVES)])
        root.add_child(seq)
    tree = py_trees.trees.BehaviourTree(root)
    assert sum(1 for _ in root.iterate()) == 100
    tree.setup()
    return tree.tick


def btcpp_tick(board_heavy: bool = False) -> Callable[[], object]:
    board = btpy.Blackboard.create()
    for key, value in host_entries().items():
        board.set_int(key, value)
    tree = btpy.BehaviorTreeFactory().create_tree_from_text(tree_xml(board_heavy), board)
    return tree.tick_exactly_once


def median_us(tick: Callable[[], object]) -> float:
    for _ in range(200):
        tick()
    rounds = []
    for _ in range(ROUNDS):
        start = time.perf_counter()
        for _ in range(TICKS):
            tick()
        rounds.append((time.perf_counter() - start) / TICKS * 1e6)
    return statistics.median(rounds)


def report(label: str, board_heavy: bool) -> None:
    ours = median_us(coral_tick(board_heavy))
    theirs = median_us(py_trees_tick(board_heavy))
    native = median_us(btcpp_tick(board_heavy))
    ratio = ours / theirs
    print(
        f"BENCH name=bt_tick_{label}_coral value={ours:.1f} unit=us target=<={0.3 * theirs:.1f} "
        f"result={'ok' if ratio <= 0.3 else 'miss'}"
    )
    print(f"BENCH name=bt_tick_{label}_py_trees value={theirs:.1f} unit=us target=>0 result=ok")
    print(f"BENCH name=bt_tick_{label}_btcpp value={native:.1f} unit=us target=>0 result=ok")
    suffix = "" if label == "100_nodes" else f"_{label}"
    print(
        f"BENCH name=bt_tick_ratio_coral_to_py_trees{suffix} value={ratio:.3f} unit=ratio target=<=0.3 "
        f"result={'ok' if ratio <= 0.3 else 'miss'}"
    )


def main() -> None:
    report("100_nodes", board_heavy=False)
    report("blackboard_100_nodes", board_heavy=True)


if __name__ == "__main__":
    main()
