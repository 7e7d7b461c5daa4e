"""The engine's deliberate differences from the BT.CPP release the differential tests run (4.8.2),
one test each; docs/bt-engine.md lists them with their reasons."""

from __future__ import annotations

import coral_core.bt as bt
from bt_stubs import S, make_tree
from coral_core.bt.blackboard import Blackboard
from coral_core.bt.builder import literal_value
from coral_core.bt.scripting import ScriptEnv, compile_script


def run(code: str) -> object:
    return compile_script(code)(ScriptEnv(Blackboard(), {}))


def test_scripts_follow_the_4_10_grammar_and_precedence() -> None:
    # 4.8 refuses `+` next to `&` without parentheses and gives && and || one precedence level.
    assert run("1 + 2 & 3") == 3.0
    assert run("1 || 0 && 0") == 1.0


def test_a_numeric_subtree_literal_is_a_number_as_in_4_10() -> None:
    tree, _ = make_tree(
        '<SubTree ID="S" n="3"/>',
        trees='<BehaviorTree ID="S"><Script code="m := n + 1; @out := m"/></BehaviorTree>',
    )
    assert tree.tick_exactly_once() == S
    assert tree.root_blackboard.get("out") == 4.0


def test_switch_matches_whole_numbers_only_as_in_4_10() -> None:
    # 4.8 reads the numeric prefix of "2.5" and would pick case_1="2".
    tree, queues = make_tree(
        '<Switch2 variable="{x}" case_1="2" case_2="3"><Q name="two"/><Q name="three"/><Q name="other"/>'
        "</Switch2>",
        {"two": [S], "three": [S], "other": [S]},
        blackboard={"x": "2.5"},
    )
    assert tree.tick_exactly_once() == S
    assert queues.calls == {"other": 1}


def test_static_validation_points_out_numeric_literals_with_trailing_text() -> None:
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Repeat num_cycles="3x">'
        "<AlwaysSuccess/></Repeat></BehaviorTree></root>"
    )
    registry = bt.NodeRegistry.with_builtins()
    doc = bt.load_tree_text(xml, registry)
    assert any("trailing text" in str(e) for e in bt.validate_document(doc, registry))
    # Building still does what BT.CPP does: the prefix 3 is used.
    tree = bt.build_tree(doc, registry)
    statuses = [tree.tick_exactly_once() for _ in range(3)]  # Repeat yields between cycles
    assert statuses == [bt.Status.RUNNING, bt.Status.RUNNING, bt.Status.SUCCESS]


def test_a_loop_reads_a_text_entry_as_a_queue_as_in_4_10() -> None:
    # 4.8 refuses a text entry that no queue port declared; here it is a SubTree literal.
    tree, queues = make_tree(
        '<SubTree ID="S" lq="4;5"/>',
        {"each": [S]},
        trees='<BehaviorTree ID="S"><LoopInt queue="{lq}" value="{@v}"><Q name="each"/></LoopInt>'
        "</BehaviorTree>",
    )
    statuses = [tree.tick_exactly_once() for _ in range(3)]
    assert statuses == [bt.Status.RUNNING, bt.Status.RUNNING, S]
    assert queues.calls == {"each": 2} and tree.root_blackboard.get("v") == 5


def test_true_and_false_are_doubles_as_in_4_10() -> None:
    # 4.8 makes them the integers 1 and 0, which print as "1" once stored.
    assert run("t := true; t") == 1.0 and isinstance(run("t := true; t"), float)
    assert run("'x' .. false") == "x0.000000"


def test_a_subtree_literal_is_a_number_only_when_all_of_it_is_one() -> None:
    # 4.10 reads the literal with std::from_chars and keeps it only if nothing is left over.
    assert [literal_value(t) for t in ["2", "-3", "1e0", ".5", "inf"]] == [2, -3, 1.0, 0.5, float("inf")]
    assert [literal_value(t) for t in [" 2", "+2", "0x2", "1_0", "3abc", "1;2", "1e999"]] == [
        " 2",
        "+2",
        "0x2",
        "1_0",
        "3abc",
        "1;2",
        "1e999",
    ]
