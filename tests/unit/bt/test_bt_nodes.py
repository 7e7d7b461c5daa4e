"""Built-in nodes tick by tick, with scripted leaves (statuses asserted after every tick)."""

from __future__ import annotations

import coral_core.bt as bt
import pytest
from bt_stubs import F, K, R, S, make_tree

CASES = [
    (
        "a sequence resumes at its running child without re-ticking earlier ones",
        '<Sequence><Q name="a"/><Q name="b"/></Sequence>',
        {"a": [S], "b": [R, S]},
        [R, S],
        {"a": 1, "b": 2},
    ),
    (
        "a fallback returns the first success",
        '<Fallback><Q name="a"/><Q name="b"/></Fallback>',
        {"a": [F], "b": [S]},
        [S],
        {"a": 1, "b": 1},
    ),
    (
        "a reactive sequence re-ticks its condition every tick",
        '<ReactiveSequence><Q name="c"/><Q name="a"/></ReactiveSequence>',
        {"c": [S], "a": [R, R, S]},
        [R, R, S],
        {"c": 3, "a": 3},
    ),
    (
        "a memory sequence resumes at the failed child",
        '<SequenceWithMemory><Q name="a"/><Q name="b"/></SequenceWithMemory>',
        {"a": [S], "b": [F, S]},
        [R, F, S],
        {"a": 1, "b": 2},
    ),
    (
        "parallel -1/1 over S,S,F fails",
        '<Parallel success_count="-1" failure_count="1"><Q name="a"/><Q name="b"/><Q name="c"/></Parallel>',
        {"a": [S], "b": [S], "c": [F]},
        [F],
        {},
    ),
    (
        "parallel -2/-1 over S,S,F succeeds",
        '<Parallel success_count="-2" failure_count="-1"><Q name="a"/><Q name="b"/><Q name="c"/></Parallel>',
        {"a": [S], "b": [S], "c": [F]},
        [S],
        {},
    ),
    (
        "parallel 3/2 fails as soon as success is impossible",
        '<Parallel success_count="3" failure_count="2"><Q name="a"/><Q name="b"/><Q name="c"/></Parallel>',
        {"a": [F], "b": [S], "c": [S]},
        [F],
        {"b": 0, "c": 0},
    ),
    (
        "parallel does not re-tick completed children",
        '<Parallel success_count="-1"><Q name="a"/><Q name="b"/></Parallel>',
        {"a": [S], "b": [R, R, S]},
        [R, R, S],
        {"a": 1, "b": 3},
    ),
    (
        "if-then-else latches its branch",
        '<IfThenElse><Q name="c"/><Q name="t"/><Q name="e"/></IfThenElse>',
        {"c": [S, F], "t": [R, S], "e": [S]},
        [R, S],
        {"c": 1, "t": 2, "e": 0},
    ),
    (
        "try-catch runs the catch and fails",
        '<TryCatch><Q name="a"/><Q name="b"/><Q name="c"/></TryCatch>',
        {"a": [S], "b": [F], "c": [S]},
        [F],
        {"a": 1, "b": 1, "c": 1},
    ),
    (
        "try-catch succeeds when the try succeeds",
        '<TryCatch><Q name="a"/><Q name="c"/></TryCatch>',
        {"a": [R, S], "c": [S]},
        [R, S],
        {"c": 0},
    ),
    ("inverter flips", '<Inverter><Q name="a"/></Inverter>', {"a": [S]}, [F], {}),
    (
        "keep running until failure",
        '<KeepRunningUntilFailure><Q name="a"/></KeepRunningUntilFailure>',
        {"a": [S, S, F]},
        [R, R, F],
        {},
    ),
    (
        "repeat 3 yields after each synchronous success",
        '<Repeat num_cycles="3"><Q name="a"/></Repeat>',
        {"a": [S]},
        [R, R, S],
        {"a": 3},
    ),
    (
        "retry -1 retries forever",
        '<RetryUntilSuccessful num_attempts="-1"><Q name="a"/></RetryUntilSuccessful>',
        {"a": [F, F, F, S]},
        [R, R, R, S],
        {"a": 4},
    ),
    (
        "retry 2 gives up",
        '<RetryUntilSuccessful num_attempts="2"><Q name="a"/></RetryUntilSuccessful>',
        {"a": [F]},
        [R, F],
        {"a": 2},
    ),
    ("run once then skips", '<RunOnce><Q name="a"/></RunOnce>', {"a": [S]}, [S, K, K], {"a": 1}),
    (
        "run once replays its result",
        '<RunOnce then_skip="false"><Q name="a"/></RunOnce>',
        {"a": [F]},
        [F, F],
        {"a": 1},
    ),
    (
        "precondition false returns else without ticking",
        '<Precondition if="1 &gt; 2" else="RUNNING"><Q name="a"/></Precondition>',
        {"a": [S]},
        [R, R],
        {"a": 0},
    ),
    (
        "all-skipped sequence is skipped",
        '<Sequence><Q name="a" _skipIf="true"/></Sequence>',
        {"a": [S]},
        [K],
        {"a": 0},
    ),
    ("_successIf short-cuts the tick", '<Q name="a" _successIf="1 == 1"/>', {"a": [F]}, [S], {"a": 0}),
    (
        "switch picks the matching case",
        '<Switch2 variable="B" case_1="A" case_2="B"><Q name="a"/><Q name="b"/><Q name="d"/></Switch2>',
        {"a": [S], "b": [F], "d": [S]},
        [F],
        {"a": 0, "b": 1, "d": 0},
    ),
    (
        "async sequence yields between synchronous children",
        '<AsyncSequence><Q name="a"/><Q name="b"/></AsyncSequence>',
        {"a": [S], "b": [S]},
        [R, S],
        {"a": 1, "b": 1},
    ),
]


@pytest.mark.parametrize(("title", "body", "scripts", "expected", "calls"), CASES, ids=[c[0] for c in CASES])
def test_builtin_node(title: str, body: str, scripts: dict, expected: list, calls: dict) -> None:
    tree, queues = make_tree(body, scripts)
    assert [tree.tick_exactly_once() for _ in expected] == expected
    for name, count in calls.items():
        assert queues.calls.get(name, 0) == count, name


def test_every_node_reads_idle_after_the_tree_completes() -> None:
    tree, _ = make_tree(
        '<Sequence><Q name="a"/><Inverter><Q name="b"/></Inverter></Sequence>', {"a": [S], "b": [F]}
    )
    assert tree.tick_exactly_once() == S
    snap = tree.snapshot()
    assert all(n.status == bt.Status.IDLE for n in snap.nodes)
    assert [n.last_result for n in snap.nodes] == [S, S, S, F]


def test_tick_once_collapses_wake_ups_into_one_call() -> None:
    tree, queues = make_tree(
        '<RetryUntilSuccessful num_attempts="-1"><Q name="a"/></RetryUntilSuccessful>', {"a": [F] * 25 + [S]}
    )
    assert tree.tick_once() == S
    assert queues.calls["a"] == 26


def test_a_reactive_sequence_halts_the_running_child_when_the_condition_fails() -> None:
    tree, queues = make_tree(
        '<ReactiveSequence><Q name="c"/><Q name="a"/></ReactiveSequence>', {"c": [S, F], "a": [R]}
    )
    assert tree.tick_exactly_once() == R
    assert tree.tick_exactly_once() == F
    assert queues.halted == ["a"]


def test_halted_sleep_runs_on_halted_but_not_post() -> None:
    body = (
        '<Parallel success_count="-1" failure_count="1">'
        '<Sleep msec="5000" _onHalted="test := \'halted\'" _post="test := \'post\'"/><AlwaysFailure/>'
        "</Parallel>"
    )
    tree, _ = make_tree("<Sequence><Script code=\"test := ''\"/>" + body + "</Sequence>")
    assert tree.tick_exactly_once() == F
    assert tree.root_blackboard.get("test") == "halted"


def test_timeout_halts_its_running_child_from_the_timer() -> None:
    import time

    tree, queues = make_tree('<Timeout msec="30"><Q name="a"/></Timeout>', {"a": [R]})
    assert tree.tick_exactly_once() == R
    deadline = time.monotonic() + 5
    while "a" not in queues.halted and time.monotonic() < deadline:
        tree.wait_for_wake_up(0.05)
    assert queues.halted == ["a"]
    calls = queues.calls["a"]
    assert tree.tick_exactly_once() == F
    assert queues.calls["a"] == calls  # the expired child is not ticked again


def test_sleep_wakes_tick_while_running_up() -> None:
    import time

    tree, _ = make_tree('<Sequence><Sleep msec="50"/><AlwaysSuccess/></Sequence>')
    start = time.monotonic()
    assert tree.tick_while_running(sleep_s=5.0) == S
    assert 0.04 <= time.monotonic() - start < 2.0


def test_subtree_ports_remap_literals_and_autoremap() -> None:
    trees = (
        '<BehaviorTree ID="Sub"><Script code="out := inp + 1; seen := shared"/></BehaviorTree>'
        '<BehaviorTree ID="Auto"><Script code="shared := \'changed\'; _private := 1"/></BehaviorTree>'
    )
    body = (
        '<Sequence><Script code="shared := \'x\'"/><SubTree ID="Sub" inp="41" out="{result}" '
        'shared="{=}" seen="{seen}"/><SubTree ID="Auto" _autoremap="true"/></Sequence>'
    )
    tree, _ = make_tree(body, trees=trees)
    assert tree.tick_exactly_once() == S
    board = tree.root_blackboard
    assert board.get("result") == 42
    assert board.get("seen") == "x" and board.get("shared") == "changed"
    assert not board.has("_private")


def test_loop_double_pops_one_value_per_iteration() -> None:
    body = '<LoopDouble queue="1;2;3" value="{x}"><Script code="total := total + x"/></LoopDouble>'
    tree, _ = make_tree(body, blackboard={"total": 0.0})
    assert [tree.tick_exactly_once() for _ in range(4)] == [R, R, R, S]
    assert tree.root_blackboard.get("total") == 6.0


def test_skip_unless_updated_ticks_only_after_a_write() -> None:
    body = (
        '<Sequence><SkipUnlessUpdated entry="{v}"><Script code="n := n + 1"/></SkipUnlessUpdated></Sequence>'
    )
    tree, _ = make_tree(body, blackboard={"v": 1, "n": 0})
    assert tree.tick_exactly_once() == S
    assert tree.tick_exactly_once() == K
    tree.root_blackboard.set("v", 2)
    assert tree.tick_exactly_once() == S
    assert tree.root_blackboard.get("n") == 2


def test_while_do_else_re_evaluates_its_condition_and_halts_the_other_branch() -> None:
    body = '<WhileDoElse><ScriptCondition code="go == 1"/><Q name="t"/><Q name="e"/></WhileDoElse>'
    tree, queues = make_tree(body, {"t": [R], "e": [S]}, blackboard={"go": 1})
    assert tree.tick_exactly_once() == R
    tree.root_blackboard.set("go", 0)
    assert tree.tick_exactly_once() == S
    assert queues.halted == ["t"] and queues.calls["e"] == 1


def test_if_then_else_is_not_reactive() -> None:
    body = '<IfThenElse><ScriptCondition code="go == 1"/><Q name="t"/><Q name="e"/></IfThenElse>'
    tree, queues = make_tree(body, {"t": [R, S], "e": [S]}, blackboard={"go": 1})
    assert tree.tick_exactly_once() == R
    tree.root_blackboard.set("go", 0)
    assert tree.tick_exactly_once() == S
    assert queues.calls.get("e", 0) == 0 and not queues.halted


def test_try_catch_returns_failure_even_while_the_catch_runs_to_completion() -> None:
    tree, queues = make_tree(
        '<TryCatch><Q name="a"/><Q name="b"/><Q name="c"/></TryCatch>', {"a": [S], "b": [F], "c": [R, S]}
    )
    assert tree.tick_exactly_once() == R  # the catch is RUNNING
    assert tree.tick_exactly_once() == F
    assert queues.calls == {"a": 1, "b": 1, "c": 2}


def test_try_catch_with_catch_on_halt_runs_the_catch_when_halted_during_the_try() -> None:
    tree, queues = make_tree(
        '<TryCatch catch_on_halt="true"><Q name="a"/><Q name="c"/></TryCatch>', {"a": [R], "c": [S]}
    )
    assert tree.tick_exactly_once() == R
    tree.halt()
    assert queues.halted == ["a"] and queues.calls["c"] == 1


def test_try_catch_without_catch_on_halt_does_not_run_the_catch_on_halt() -> None:
    tree, queues = make_tree('<TryCatch><Q name="a"/><Q name="c"/></TryCatch>', {"a": [R], "c": [S]})
    tree.tick_exactly_once()
    tree.halt()
    assert queues.halted == ["a"] and "c" not in queues.calls


def test_delay_ticks_its_child_only_after_the_wall_clock_delay() -> None:
    import time

    tree, queues = make_tree('<Delay delay_msec="40"><Q name="a"/></Delay>', {"a": [S]})
    start = time.monotonic()
    assert tree.tick_exactly_once() == R
    assert "a" not in queues.calls
    assert tree.tick_while_running(sleep_s=5.0) == S
    assert time.monotonic() - start >= 0.035 and queues.calls["a"] == 1


def test_a_zero_delay_runs_its_child_at_the_next_tick() -> None:
    # BT.CPP's timer thread fires at once; the engine does not leave it to a thread waiting for
    # the GIL, which three quick ticks in a row used to outrun.
    tree, queues = make_tree('<Delay delay_msec="0"><Q name="a"/></Delay>', {"a": [S, S]})
    assert tree.tick_exactly_once() == R and "a" not in queues.calls
    assert tree.tick_exactly_once() == S and queues.calls["a"] == 1
    assert tree.tick_once() == S and queues.calls["a"] == 2  # tick_once re-ticks on the wake-up


def test_plugin_controls_and_decorators_register_like_leaves() -> None:
    from coral_core.bt.leaves import ControlNode, DecoratorNode

    class FirstOnly(ControlNode):
        def tick(self) -> int:
            self.set_status(R)
            st = self.children[0].execute_tick()
            if st != R:
                self.reset_children()
            return st

    class Twice(DecoratorNode):
        def tick(self) -> int:
            self.set_status(R)
            self.children[0].execute_tick()
            self.reset_child()
            return self.children[0].execute_tick()

    registry = bt.NodeRegistry.with_builtins()
    registry.register("FirstOnly", FirstOnly)
    registry.register("Twice", Twice)
    assert registry.spec("FirstOnly").kind == bt.NodeKind.CONTROL
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M"><FirstOnly><Twice><Script code="n := n + 1"/></Twice>'
        "<AlwaysFailure/></FirstOnly></BehaviorTree></root>"
    )
    tree = bt.build_tree(bt.load_tree_text(xml, registry), registry, blackboard={"n": 0})
    assert tree.tick_exactly_once() == S
    assert tree.root_blackboard.get("n") == 2


@pytest.mark.parametrize("value", ["-1", "5"])
def test_a_number_outside_node_status_is_a_clear_error(value: str) -> None:
    # BT.CPP returns such a number as the node's status and crashes; the engine refuses it.
    tree, _ = make_tree(
        f'<Sequence><Script code="x := {value}"/>'
        '<Precondition if="0" else="{x}"><Q name="q"/></Precondition></Sequence>'
    )
    with pytest.raises(bt.BTRuntimeError, match=f"{value} is no NodeStatus"):
        tree.tick_exactly_once()
