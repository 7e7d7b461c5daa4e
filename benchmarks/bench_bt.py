"""Tick time of 100-node all-synchronous trees in coral_core.bt, stock py_trees (same shape) and BT.CPP
(behaviortreepy); prints BENCH lines including coral's ratio to py_trees against the 0.3 target.

Two trees: one of constant leaves, and a blackboard-heavy one whose every leaf reads or writes an
entry (coral/BT.CPP: Script `k := k + 1` and ScriptCondition `k > 0`; py_trees:
SetBlackboardVariable and CheckBlackboardVariableValue).

Then the Groot2 publisher: the tick of the same 100-node tree published with a client polling
STATUS every 50 ms against the tree unpublished (target <= 1.1x), and 2,000 random trees read
through Groot2 in BT.CPP's publisher and ours (the differential test runs a sample of them).

Run with `make bench-bt` (or `.venv/bin/python benchmarks/bench_bt.py`).
"""

from __future__ import annotations

import operator
import statistics
import time
from collections.abc import Callable

import behaviortreepy as btpy
import coral_core.bt as bt
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
    tree = bt.build_tree(doc, registry, blackboard=host_entries())
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


# A Groot2 client in its own process: STATUS every 50 ms, as Groot2 polls, until stdin closes.
POLLING_CLIENT = """
import select, struct, sys, time, zmq
socket = zmq.Context().socket(zmq.REQ)
socket.setsockopt(zmq.RCVTIMEO, 2000)
socket.connect("tcp://127.0.0.1:" + sys.argv[1])
answered = 0
while not select.select([sys.stdin], [], [], 0.05)[0]:
    socket.send(struct.pack("<BBI", 2, ord("S"), answered))
    answered += len(socket.recv_multipart()[1]) == 300
print(answered)
"""


def report_groot2() -> None:
    """Tick cost of the 100-node tree published over Groot2 with a client polling STATUS every
    50 ms, against the same tree unpublished, in interleaved rounds of one run (the client polls
    throughout, so both sides share the machine's load alike)."""
    import subprocess
    import sys

    import zmq
    from coral_core.bt.groot2 import Groot2Publisher

    plain = coral_tick()
    registry = bt.NodeRegistry.with_builtins()
    tree = bt.build_tree(bt.load_tree_text(tree_xml(), registry), registry, blackboard=host_entries())
    port = 21667
    while True:
        try:
            publisher = Groot2Publisher(tree, port)
            break
        except zmq.ZMQError:
            port += 2
    client = subprocess.Popen(
        [sys.executable, "-c", POLLING_CLIENT, str(port)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        if not publisher.wait_for_client(30):
            raise RuntimeError("the polling client never connected")
        for _ in range(200):
            plain()
            tree.tick_exactly_once()
        alone, watched = [], []
        for _ in range(ROUNDS * 3):
            for tick, out in ((plain, alone), (tree.tick_exactly_once, watched)):
                start = time.perf_counter()
                for _ in range(TICKS):
                    tick()
                out.append((time.perf_counter() - start) / TICKS * 1e6)
        answered = int(client.communicate("", timeout=30)[0])
    finally:
        if client.poll() is None:
            client.kill()
        publisher.close()
    ours, base = statistics.median(watched), statistics.median(alone)
    ratio = ours / base
    print(f"BENCH name=bt_tick_100_nodes_groot2_polled value={ours:.1f} unit=us target=>0 result=ok")
    print(f"BENCH name=bt_tick_100_nodes_unpublished value={base:.1f} unit=us target=>0 result=ok")
    print(f"BENCH name=bt_groot2_status_polls value={answered} unit=requests target=>0 result=ok")
    print(
        f"BENCH name=bt_tick_ratio_groot2_polled_to_unpublished value={ratio:.3f} unit=ratio "
        f"target=<=1.1 result={'ok' if ratio <= 1.1 else 'miss'}"
    )


def report_groot2_differential(trees: int = 2000) -> None:
    """Random trees read through Groot2 in BT.CPP's publisher and ours (acceptance 1 of issue 49)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "conformance"))
    from bt_groot2_differential import Report, compare, random_requests

    report = compare(random_requests(range(trees)), Report())
    for line in report.mismatches[:5]:
        print(line)
    print(
        f"BENCH name=bt_groot2_differential_agreeing value={report.agreeing} unit=trees "
        f"target=>={trees} result={'ok' if report.agreeing >= trees else 'miss'}"
    )
    print(f"BENCH name=bt_groot2_differential_seconds value={report.seconds:.0f} unit=s target=>0 result=ok")


def main() -> None:
    report("100_nodes", board_heavy=False)
    report("blackboard_100_nodes", board_heavy=True)
    report_groot2()
    report_groot2_differential()


if __name__ == "__main__":
    main()
