"""One small tree per blackboard/script/SubTree/halt rule where the engine once differed from BT.CPP.

Each tree runs in real BT.CPP (behaviortreepy) and in coral_core.bt with the same scripted leaves; the
whole trace must agree (per tick: root status, leaf calls with the blackboard each leaf sees, the root
blackboard as `std::to_string` prints it; then haltTree()), and each test also pins what BT.CPP did,
so a change in either engine shows up.
"""

from __future__ import annotations

import pytest
from bt_harness import EMPTY_TEXT, ERROR, Outcomes, Run, run_btcpp, run_coral


def both(
    body: str,
    subtrees: str = "",
    *,
    ticks: int = 1,
    host: dict[str, object] | None = None,
    leaves: dict[str, list[int]] | None = None,
) -> Run:
    xml = (
        f'<root BTCPP_format="4" main_tree_to_execute="M"><BehaviorTree ID="M">{body}</BehaviorTree>'
        f"{subtrees}</root>"
    )
    # Node transitions are left to the random differential test (it batches BT.CPP's file logger).
    theirs = run_btcpp(
        xml, Outcomes(dict(leaves or {})), ticks, host_vars=host, observe=True, log_transitions=False
    )
    ours = run_coral(xml, Outcomes(dict(leaves or {})), ticks, host_vars=host, observe=True)
    assert ours.trace(False) == theirs.trace(False), f"BT.CPP: {theirs.error}\ncoral: {ours.error}"
    return theirs


def sub(tree_id: str, body: str) -> str:
    return f'<BehaviorTree ID="{tree_id}">{body}</BehaviorTree>'


# 1. typed entries ---------------------------------------------------------------------------
def test_a_script_value_in_a_port_declared_entry_keeps_its_own_type() -> None:
    run = both(
        '<Sequence><Script code="sw := 2"/><Script code="r := sw + 1"/>'
        '<Switch2 variable="{sw}" case_1="2" case_2="3"><AlwaysSuccess/><AlwaysFailure/>'
        "<AlwaysFailure/></Switch2></Sequence>"
    )
    assert run.statuses == [2] and run.boards[-1] == {"r": "3.000000", "sw": "2"}


def test_a_port_of_another_type_writing_a_typed_entry_throws() -> None:
    # LoopInt's first write types the entry int; LoopDouble's 1.5 may not change that.
    run = both(
        '<Sequence><SkipUnlessUpdated entry="{k}"><AlwaysSuccess/></SkipUnlessUpdated>'
        '<LoopInt queue="1" value="{k}"><AlwaysSuccess/></LoopInt>'
        '<LoopDouble queue="1.5" value="{k}"><AlwaysSuccess/></LoopDouble></Sequence>',
        ticks=3,
    )
    assert run.statuses[-1] == ERROR and "once declared" in run.error and run.boards[-1] == {"k": "1"}


def test_a_loop_consumes_a_shared_queue_that_a_script_filled() -> None:
    run = both(
        "<Sequence><Script code=\"lq := '1;2;3'\"/>"
        '<LoopInt queue="{lq}" value="{v}"><Leaf name="L"/></LoopInt></Sequence>',
        ticks=4,
        host={"v": 0},
        leaves={"L": [2]},
    )
    assert [b["v"] for b in run.boards] == ["1", "2", "3", "3"] and run.boards[0]["lq"] == "<object>"


def test_a_loop_over_a_declared_but_empty_queue_throws() -> None:
    run = both('<LoopInt queue="{lq}" value="{v}"><AlwaysSuccess/></LoopInt>', host={"v": 0})
    assert run.statuses == [ERROR]


# 2. script assignment keeps a variable's type -------------------------------------------------
def test_assigning_a_numeric_string_to_a_number_converts_it() -> None:
    run = both("<Script code=\"a := 1; a = '5'\"/>")
    assert run.boards[-1] == {"a": "5.000000"}


def test_assigning_a_non_numeric_string_to_a_number_throws() -> None:
    run = both('<Sequence><Script code="a := 1"/><Script code="a = \'zz\'"/></Sequence>')
    assert run.statuses == [ERROR] and run.boards[-1] == {"a": "1"}


def test_an_integer_variable_refuses_a_fractional_double() -> None:
    run = both('<Script code="a := 1; b := a; b = 2.5"/>')
    assert run.statuses == [ERROR] and run.boards[-1] == {"a": "1", "b": "1"}


def test_an_integer_variable_takes_an_integral_double_as_an_integer() -> None:
    run = both('<Script code="a := 1; a = 4.0; a += 1"/>')
    assert run.boards[-1] == {"a": "5"}


def test_an_integer_beyond_2_53_stays_an_integer_and_refuses_double_arithmetic() -> None:
    # 1e17 is an exact double; stored in an int entry it is an int that no double holds exactly
    # once it grows, so BT.CPP refuses to widen it again ("Loss of precision").
    run = both('<Sequence><Script code="a := 1; a *= 1e17"/><Script code="c := a + 0"/></Sequence>')
    assert run.statuses == [ERROR] and "Loss of precision" in run.error
    assert run.boards[-1] == {"a": "100000000000000000", "c": EMPTY_TEXT}


@pytest.mark.parametrize(
    "code, cause",
    [
        ("c := -a", "Loss of precision"),
        ("c := (a == 1)", "Loss of precision"),
        ("c := (a ? 1 : 2)", "Loss of precision"),
        ("a += 1", "Loss of precision"),
        # Both sides become doubles before BT.CPP looks at the operator.
        ("c := (a & 1)", "Loss of precision"),
        ("c := (a .. 1)", "Loss of precision"),
        ("c := (1e19 & 1)", "not an integer"),
    ],
)
def test_every_operator_refuses_an_integer_no_double_holds(code: str, cause: str) -> None:
    run = both(f'<Sequence><Script code="a := 1; a *= 1e17"/><Script code="{code}"/></Sequence>')
    assert run.statuses == [ERROR] and cause in run.error


# 3. script operators -------------------------------------------------------------------------
def test_concatenation_prints_doubles_like_std_to_string() -> None:
    run = both("<Script code=\"s := 'ab' .. 1.0; t := 'ab' .. 1; u := 'x' .. (1/3)\"/>")
    assert run.boards[-1] == {"s": "ab1.000000", "t": "ab1", "u": "x0.333333"}


def test_concatenating_two_numbers_gives_an_empty_value() -> None:
    run = both('<Sequence><Script code="x := 1 .. 2"/></Sequence>')
    assert run.statuses == [ERROR] and "not initialized" in run.error


def test_a_chained_comparison_stops_at_the_first_false_pair() -> None:
    run = both('<ScriptCondition code="5 &lt; 1 &lt;= zz"/>')
    assert run.statuses == [3]


def test_division_by_zero_is_ieee() -> None:
    run = both('<Script code="u := 1/0; v := -1/0; w := 0/0"/>')
    assert run.boards[-1] == {"u": "inf", "v": "-inf", "w": "-nan"}


@pytest.mark.parametrize("code", ["s := 'ab'; t := -s", "s := 'ab'; t := !s", "e := 1; UnsetE"])
def test_unary_operators_refuse_strings_and_empty_entries(code: str) -> None:
    if code.endswith("UnsetE"):
        # `k` is declared (empty) by the SkipUnlessUpdated port but never written.
        run = both(
            '<Sequence><SkipUnlessUpdated entry="{k}"><AlwaysSuccess/></SkipUnlessUpdated>'
            '<Script code="t := -k"/></Sequence>'
        )
    else:
        run = both(f'<Script code="{code}"/>')
    assert run.statuses == [ERROR] and run.boards[-1]["t"] == EMPTY_TEXT


@pytest.mark.parametrize(
    ("code", "status", "cause"),
    [
        ("1", 2, ""),
        ("0.0", 3, ""),
        ("2.5", 2, ""),
        ("0/0", 2, ""),
        ("2", ERROR, "Implicit casting to bool"),
        ("v := 2; v", ERROR, "Implicit casting to bool"),
        ("-0.5", ERROR, "negative"),
        ("'true'", ERROR, "no known safe conversion"),
        ("''", ERROR, "no known safe conversion"),
    ],
)
def test_a_condition_takes_only_what_bt_cpp_casts_to_a_bool(code: str, status: int, cause: str) -> None:
    # The engine once read any text, count or negative number as "true".
    run = both(f'<ScriptCondition code="{code}"/>')
    assert run.statuses == [status] and cause in run.error


def test_a_pre_condition_refuses_text_too() -> None:
    run = both('<Sequence><Script code="t := \'a\'"/><AlwaysSuccess _skipIf="t"/></Sequence>')
    assert run.statuses == [ERROR] and "no known safe conversion" in run.error


@pytest.mark.parametrize(
    ("code", "status"), [("(1) &amp;&amp; (0.5)", 2), ("(2) &amp;&amp; (1)", ERROR), ("(1) || (-1)", ERROR)]
)
def test_logic_operators_cast_both_sides_to_bool(code: str, status: int) -> None:
    run = both(f'<ScriptCondition code="{code}"/>')
    assert run.statuses == [status]
    assert status != ERROR or "Logic operators are not allowed" in run.error


@pytest.mark.parametrize(
    ("code", "status"),
    [
        ("'12abc' == 12", 2),
        ("' +5' == 5", 2),
        ("'0x1F' == 31", 2),
        ("'1_0' == 1", 2),
        ("('0') ? (1.0) : (0.0)", 3),
        ("('12abc') ? (1.0) : (0.0)", 2),
        ("('a') ? (1.0) : (0.0)", ERROR),
    ],
)
def test_text_read_as_a_number_is_its_leading_number(code: str, status: int) -> None:
    # BT.CPP reads text with std::stod: blanks, a sign, hex, then whatever number starts it.
    run = both(f'<ScriptCondition code="{code}"/>')
    assert run.statuses == [status]


@pytest.mark.parametrize("op", ["&lt;", "&gt;", "&lt;=", "&gt;="])
def test_every_ordering_holds_for_nan(op: str) -> None:
    # BT.CPP fails `a < b` only when `a >= b`, which is never true of NaN.
    run = both(f'<ScriptCondition code="(0/0) {op} 1"/>')
    assert run.statuses == [2]


def test_complement_of_nan_is_the_largest_integer() -> None:
    run = both('<Script code="t := ~(0/0); u := t &gt; 9e18"/>')
    assert run.boards[-1]["u"] == "1.000000"


def test_a_bool_entry_is_copied_on_as_an_integer() -> None:
    run = both('<Script code="t := b"/>', host={"b": True})
    assert run.boards[-1]["t"] == "1"


# 3b. typed ports reading entries -------------------------------------------------------------
def test_run_once_keeps_its_default_when_then_skip_does_not_convert() -> None:
    # BT.CPP ignores a failed getInput here and skips after the first run, as by default
    # (status 4 is SKIPPED).
    run = both('<RunOnce then_skip="{b}"><AlwaysSuccess/></RunOnce>', ticks=2, host={"b": "maybe"})
    assert run.statuses == [2, 4]
    run = both(
        '<Sequence><Script code="b := 2"/><RunOnce then_skip="{b}"><AlwaysSuccess/></RunOnce></Sequence>',
        ticks=2,
    )
    assert run.statuses == [2, 2]  # the Sequence succeeds over its skipped last child


def test_a_port_of_int_refuses_an_infinite_double() -> None:
    run = both(
        '<Sequence><Script code="x := (1/0)"/><Repeat num_cycles="{x}"><AlwaysSuccess/></Repeat></Sequence>'
    )
    assert run.statuses == [ERROR] and "Missing parameter [num_cycles]" in run.error


def test_set_blackboard_parses_text_into_a_queue_entry() -> None:
    run = both(
        '<Sequence><SetBlackboard value="4;5" output_key="q"/>'
        '<LoopInt queue="{q}" value="{o}"><AlwaysSuccess/></LoopInt></Sequence>'
    )
    assert run.statuses == [1] and run.boards[-1]["o"] == "4"


def test_set_blackboard_replaces_the_value_of_a_typed_entry_with_the_parsed_text() -> None:
    # The int entry (declared by Repeat's port) held the double a script wrote first.
    run = both(
        '<Sequence><Script code="x := 2.5"/><SetBlackboard value="-1" output_key="x"/>'
        '<Repeat num_cycles="{x}"><AlwaysSuccess/></Repeat></Sequence>'
    )
    assert run.boards[-1] == {"x": "-1"}


@pytest.mark.parametrize(
    "writer", ['<SetBlackboard value="SUCCESS" output_key="x"/>', "<Script code=\"x := 'SUCCESS'\"/>"]
)
def test_text_is_refused_by_an_entry_of_node_status(writer: str) -> None:
    # NodeStatus is an enum: BT.CPP gives its entries no string converter.
    run = both(
        f'<Sequence>{writer}<Precondition if="0" else="{{x}}"><AlwaysSuccess/></Precondition></Sequence>'
    )
    assert run.statuses == [ERROR]


@pytest.mark.parametrize(("value", "status"), [("3", 3), ("4", 2), ("2.5", ERROR), ("(0/0)", ERROR)])
def test_a_node_status_port_takes_an_integral_number(value: str, status: int) -> None:
    # 4 is SKIPPED, so the Sequence goes on and succeeds.
    run = both(
        f'<Sequence><Script code="x := {value}"/>'
        '<Precondition if="0" else="{x}"><AlwaysSuccess/></Precondition></Sequence>'
    )
    assert run.statuses == [status]


@pytest.mark.parametrize("node", ['<Sleep msec="-1"/>', '<Delay delay_msec="-5"><AlwaysSuccess/></Delay>'])
def test_a_negative_literal_for_an_unsigned_port_is_a_load_error(node: str) -> None:
    run = both(node)
    assert run.verdict == "REJECT" and "can not be converted to unsigned" in run.error


@pytest.mark.parametrize(
    ("node", "loads"),
    [
        ('<Repeat num_cycles="2147483647"><AlwaysFailure/></Repeat>', True),
        ('<Repeat num_cycles="2147483648"><AlwaysFailure/></Repeat>', False),
        ('<RetryUntilSuccessful num_attempts="-2147483649"><AlwaysFailure/></RetryUntilSuccessful>', False),
        ('<Parallel success_count="99999999999999999999"><AlwaysSuccess/></Parallel>', False),
        ('<Delay delay_msec="4294967295"><AlwaysSuccess/></Delay>', True),
        ('<Sleep msec="4294967296"/>', False),
        ('<Timeout msec="99999999999999999999"><AlwaysSuccess/></Timeout>', False),
        ('<LoopInt queue="1;2147483647" value="{v}"><AlwaysSuccess/></LoopInt>', True),
        ('<LoopInt queue="1;-2147483649" value="{v}"><AlwaysSuccess/></LoopInt>', False),
        ('<Script code="x := 9223372036854775807"/>', True),
        ('<Script code="x := 9223372036854775808"/>', False),
        ('<Script code="x := 0x8000000000000000"/>', False),
        ('<Script code="x := 1e308"/>', True),
        ('<Script code="x := 1e309"/>', False),
        ('<Script code="x := 1e-310"/>', False),
    ],
)
def test_a_literal_outside_its_ports_cpp_type_is_a_load_error(node: str, loads: bool) -> None:
    # BT.CPP's own nodes declare `int` and `unsigned`: 32 bits, whatever Python's ints hold. A
    # script's integer literal is an int64, and its other numbers go through std::stod.
    run = both(node)
    assert (run.verdict == "LOADED") == loads, run.error


@pytest.mark.parametrize("code", ["x := 3000000000", "x := -2147483649", "x := 2147483647"])
def test_an_int_port_refuses_an_entry_outside_32_bits_when_it_reads_it(code: str) -> None:
    run = both(
        f'<Sequence><Script code="{code}"/><Repeat num_cycles="{{x}}"><AlwaysFailure/></Repeat></Sequence>'
    )
    fits = code.endswith("2147483647")
    assert run.statuses == ([3] if fits else [ERROR]), run.error


@pytest.mark.parametrize("node", ['<Sleep msec="{x}"/>', '<Timeout msec="{x}"><AlwaysSuccess/></Timeout>'])
def test_an_unsigned_port_refuses_a_negative_entry(node: str) -> None:
    run = both(f'<Sequence><Script code="x := -1"/>{node}</Sequence>')
    assert run.statuses == [ERROR] and "Missing parameter [msec]" in run.error


# 4. ports with no type (BT::Any) ---------------------------------------------------------------
def test_an_entry_declared_by_an_any_port_stays_untyped_for_later_typed_ports() -> None:
    # int and double ports share `k` (no load error); the integral 2.0 is stored into the int.
    run = both(
        '<Sequence><SkipUnlessUpdated entry="{k}"><AlwaysSuccess/></SkipUnlessUpdated>'
        '<LoopInt queue="1" value="{k}"><AlwaysSuccess/></LoopInt>'
        '<LoopDouble queue="2.0" value="{k}"><AlwaysSuccess/></LoopDouble></Sequence>',
        ticks=3,
    )
    assert run.verdict == "LOADED" and run.boards[-1] == {"k": "2"}


def test_an_any_port_entry_refuses_a_string_from_a_script() -> None:
    run = both(
        '<Sequence><SkipUnlessUpdated entry="{k}"><AlwaysSuccess/></SkipUnlessUpdated>'
        "<Script code=\"k := 'a'\"/></Sequence>"
    )
    assert run.statuses == [ERROR]


# 5. SetBlackboard / UnsetBlackboard --------------------------------------------------------------
def test_set_blackboard_from_a_removed_key_throws() -> None:
    run = both(
        '<Sequence><UnsetBlackboard key="src"/><SetBlackboard value="{src}" output_key="x"/></Sequence>'
    )
    assert run.statuses == [ERROR] and "Can't find the port" in run.error


def test_set_blackboard_from_an_empty_key_fails() -> None:
    run = both('<SetBlackboard value="{src}" output_key="x"/>')
    assert run.statuses == [3]


def test_set_blackboard_string_into_an_entry_without_converter_stores_empty() -> None:
    run = both('<Sequence><Script code="x := 5"/><SetBlackboard value="7" output_key="x"/></Sequence>')
    assert run.boards[-1] == {"x": EMPTY_TEXT}


def test_set_blackboard_string_into_a_host_int_entry_converts() -> None:
    run = both('<SetBlackboard value="7" output_key="v"/>', host={"v": 1})
    assert run.boards[-1] == {"v": "7"}


def test_set_blackboard_declares_a_new_entry_as_a_string() -> None:
    run = both('<Sequence><SetBlackboard value="7" output_key="n"/><Script code="n = 3"/></Sequence>')
    assert run.statuses == [ERROR] and run.boards[-1] == {"n": "'7'"}  # quoted: text


def test_unset_blackboard_in_a_subtree_removes_only_local_entries() -> None:
    run = both(
        '<Sequence><SubTree ID="S" v="{v}"/><SubTree ID="A" _autoremap="true"/></Sequence>',
        sub(
            "S",
            '<Sequence><UnsetBlackboard key="v"/><Script code="l := 1"/>'
            '<UnsetBlackboard key="l"/></Sequence>',
        )
        + sub("A", '<UnsetBlackboard key="v"/>'),
        host={"v": 1},
    )
    assert run.boards[-1] == {"v": "1"}


# 6. SubTree remapping ---------------------------------------------------------------------------
def test_a_literal_subtree_port_stays_local_with_autoremap() -> None:
    run = both(
        '<Sequence><SubTree ID="S" _autoremap="true" p="five"/><Script code="q := p"/></Sequence>',
        sub("S", '<Leaf name="L"/>'),
        leaves={"L": [2]},
    )
    assert run.calls[0] == [("L", (("p", "five"),))] and run.statuses == [ERROR]


def test_a_remapped_subtree_port_does_not_create_the_callers_entry() -> None:
    run = both(
        '<Sequence><SubTree ID="S" p="{q}"/><Script code="q = 1"/></Sequence>',
        sub("S", "<AlwaysSuccess/>"),
    )
    assert run.statuses == [ERROR] and "doesn't exist" in run.error


def test_private_and_root_keys_through_nested_subtrees() -> None:
    run = both(
        '<SubTree ID="A" _autoremap="true"/>',
        sub("A", '<Sequence><Script code="_p := 1; a := 2"/><SubTree ID="B" _autoremap="true"/></Sequence>')
        + sub("B", '<Sequence><Script code="@g := 7; a += 1"/><Leaf name="L"/></Sequence>'),
        leaves={"L": [2]},
    )
    assert run.boards[-1] == {"a": "3", "g": "7"}
    assert run.calls[0] == [("L", ())]


# 7. haltTree -----------------------------------------------------------------------------------
def test_halt_tree_runs_every_on_halted_and_halts_orphaned_running_nodes() -> None:
    run = both(
        '<Sequence _onHalted="h0 := 1"><Script code="k := 0"/>'
        '<SkipUnlessUpdated entry="{e}" _onHalted="h1 := 1">'
        '<Leaf name="A" _onHalted="k := k + 1"/></SkipUnlessUpdated>'
        '<Leaf name="B" _onHalted="hb := 1"/></Sequence>',
        host={"e": 1},
        leaves={"A": [1]},
    )
    # A is RUNNING under SkipUnlessUpdated, whose halt leaves it alone: only the final visit of
    # every node halts it, so its _onHalted runs once (k == 1); the root's runs twice.
    assert run.after_halt == {"e": "1", "h0": "1", "h1": "1", "hb": "1", "k": "1"}
    assert run.halted == ["A"]


def test_halt_tree_on_an_idle_tree_still_runs_on_halted() -> None:
    run = both('<Sequence _onHalted="k := 0"><Leaf name="A" _onHalted="k := k + 1"/></Sequence>', ticks=0)
    assert run.after_halt == {"k": "1"}


# 8. load-time checks ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "bad", ["<Inverter/>", "<Nope/>", "<Sequence/>", "<AlwaysSuccess><AlwaysSuccess/></AlwaysSuccess>"]
)
def test_a_tree_that_is_never_instantiated_is_still_verified(bad: str) -> None:
    run = both("<AlwaysSuccess/>", sub("Unused", bad))
    assert run.verdict == "REJECT"


def test_ports_of_a_tree_that_is_never_instantiated_are_not_checked() -> None:
    run = both("<AlwaysSuccess/>", sub("Unused", '<AlwaysSuccess bad="1"/>'))
    assert run.verdict == "LOADED"


def test_a_remap_joining_two_port_types_is_a_load_error() -> None:
    run = both(
        '<Sequence><Repeat num_cycles="{n}"><AlwaysSuccess/></Repeat><SubTree ID="S" n="{n}"/></Sequence>',
        sub("S", '<Precondition if="1" else="{n}"><AlwaysSuccess/></Precondition>'),
    )
    assert run.verdict == "REJECT" and "initially created" in run.error


def test_a_subtree_literal_under_autoremap_loads_and_fails_only_where_it_is_read() -> None:
    # The engine once wrote the literal into the caller's int entry while building and raised a
    # script error from build(); BT.CPP keeps it local and fails when the Repeat inside reads it.
    run = both(
        '<Sequence><Repeat num_cycles="{x}"><AlwaysSuccess/></Repeat>'
        '<SubTree ID="S" _autoremap="true" x="abc"/></Sequence>',
        sub("S", '<Repeat num_cycles="{x}"><AlwaysSuccess/></Repeat>'),
        host={"x": 1},
    )
    assert run.verdict == "TICKERR" and run.statuses == [ERROR] and run.boards[-1] == {"x": "1"}


# 5. literals BT.CPP reads its own way ----------------------------------------------------------
@pytest.mark.parametrize(
    ("body", "verdict"),
    [
        # A NodeStatus literal is read when the node needs it, so a bad one fails at the tick.
        ('<Precondition if="false" else="1"><AlwaysSuccess/></Precondition>', "TICKERR"),
        ('<Precondition if="false" else="FAILURE"><AlwaysSuccess/></Precondition>', "LOADED"),
        # A queue is text split on ';': `json:` belongs to vectors only.
        ('<LoopString queue="json:[1,2]" value="{x}"><AlwaysSuccess/></LoopString>', "LOADED"),
        ('<LoopInt queue="json:[1,2]" value="{x}"><AlwaysSuccess/></LoopInt>', "REJECT"),
        # '+' is the sign of a decimal literal, not an operator.
        ('<Script code="x := +3"/>', "LOADED"),
        ('<Script code="x := 2 ++3.5"/>', "LOADED"),
        ('<Script code="x := -+3"/>', "LOADED"),
        ('<Script code="x := + 3"/>', "REJECT"),
        ('<Script code="x := +0x10"/>', "REJECT"),
        ('<Sequence><Script code="y := 1"/><Script code="x := +y"/></Sequence>', "REJECT"),
        # Text written into an entry a built-in port declared must fit the port's C++ width.
        (
            '<Sequence><SetBlackboard output_key="x" value="2147483648"/><Repeat num_cycles="{x}">'
            "<AlwaysFailure/></Repeat></Sequence>",
            "TICKERR",
        ),
        ('<Sequence><SetBlackboard output_key="x" value="-1"/><Sleep msec="{x}"/></Sequence>', "TICKERR"),
        (
            '<Sequence><SetBlackboard output_key="x" value="1;2147483648"/><LoopInt queue="{x}" value="{v}">'
            "<AlwaysSuccess/></LoopInt></Sequence>",
            "TICKERR",
        ),
        # A blank pre- or post-condition does not load.
        ('<AlwaysSuccess _skipIf=""/>', "REJECT"),
        ('<AlwaysSuccess _post=" "/>', "REJECT"),
    ],
)
def test_literals_load_or_fail_where_bt_cpp_reads_them(body: str, verdict: str) -> None:
    run = both(body)
    assert run.verdict == verdict, run.error
