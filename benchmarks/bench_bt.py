"""Tick time of a 100-node all-synchronous tree in coral.bt, stock py_trees (same shape) and BT.CPP
(behaviortreepy); prints BENCH lines including coral's ratio to py_trees against the 0.3 target.

Run with `make bench-bt` (or `.venv/bin/python benchmarks/bench_bt.py`).
"""

from __future__ import annotations

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


def tree_xml() -> str:
    groups = "".join("<Sequence>" + "<AlwaysSuccess/>" * LEAVES + "</Sequence>" for _ in range(GROUPS))
    tree = f'<BehaviorTree ID="Main"><Sequence>{groups}</Sequence></BehaviorTree>'
    return f'<root BTCPP_format="4">{tree}</root>'


def coral_tick() -> Callable[[], object]:
    registry = bt.NodeRegistry.with_builtins()
    tree = bt.load_tree_text(tree_xml(), registry).build(registry)
    assert len(tree.nodes) == 100
    return tree.tick_exactly_once


def py_trees_tick() -> Callable[[], object]:
    root = py_trees.composites.Sequence("root", memory=True)
    for g in range(GROUPS):
        seq = py_trees.composites.Sequence(f"seq{g}", memory=True)
        seq.add_children([py_trees.behaviours.Success(f"s{g}_{i}") for i in range(LEAVES)])
        root.add_child(seq)
    tree = py_trees.trees.BehaviourTree(root)
    assert sum(1 for _ in root.iterate()) == 100
    return tree.tick


def btcpp_tick() -> Callable[[], object]:
    tree = btpy.BehaviorTreeFactory().create_tree_from_text(tree_xml())
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


def main() -> None:
    ours = median_us(coral_tick())
    theirs = median_us(py_trees_tick())
    native = median_us(btcpp_tick())
    ratio = ours / theirs
    print(
        f"BENCH name=bt_tick_100_nodes_coral value={ours:.1f} unit=us target=<={0.3 * theirs:.1f} "
        f"result={'ok' if ratio <= 0.3 else 'miss'}"
    )
    print(f"BENCH name=bt_tick_100_nodes_py_trees value={theirs:.1f} unit=us target=>0 result=ok")
    print(f"BENCH name=bt_tick_100_nodes_btcpp value={native:.1f} unit=us target=>0 result=ok")
    print(
        f"BENCH name=bt_tick_ratio_coral_to_py_trees value={ratio:.3f} unit=ratio target=<=0.3 "
        f"result={'ok' if ratio <= 0.3 else 'miss'}"
    )


if __name__ == "__main__":
    main()
