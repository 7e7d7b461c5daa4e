"""The scripting language: values, precedence, non-short-circuit logic, enums, assignment rules."""

from __future__ import annotations

import re

import pytest
from coral_core.bt.anyvalue import text_to_double
from coral_core.bt.blackboard import Blackboard
from coral_core.bt.errors import ScriptError
from coral_core.bt.scripting import ScriptEnv, compile_script

CASES = [
    ("arithmetic is done in double", "a:=5; b:=2; a/b", 2.5),
    ("precedence of * over +", "1 + 2 * 3", 7.0),
    ("chained comparisons", "1 < 2 < 3", 1.0),
    ("chained comparisons fail pairwise", "3 > 2 > 2", 0.0),
    ("string concatenation with ..", "'x' .. 5", "x5"),
    ("string plus string", "'a' + 'b'", "ab"),
    ("ternary", "2 > 1 ? 'yes' : 'no'", "yes"),
    ("hex literal", "0x10 + 1", 17.0),
    ("bitwise", "6 & 3", 2.0),
    ("unary not", "!false", 1.0),
    ("enums resolve before variables", "RED == 1", 1.0),
    ("string compared with an enum name", "'BLUE' == BLUE", 1.0),
    ("compound assignment", "x := 1; x += 2; x", 3.0),
    ("string compound assignment", "s := 'a'; s += 'b'; s", "ab"),
    ("repeated semicolons", "x := 1;; x", 1),
    ("epsilon equality", "0.1 + 0.2 == 0.3", 1.0),
    ("division by zero is IEEE", "1 / 0", float("inf")),
    ("doubles print as std::to_string does", "'ab' .. 1.0", "ab1.000000"),
]


def run(code: str) -> object:
    return compile_script(code)(ScriptEnv(Blackboard(), {"RED": 1, "BLUE": 2}))


@pytest.mark.parametrize(("title", "code", "expected"), CASES, ids=[c[0] for c in CASES])
def test_script_value(title: str, code: str, expected: object) -> None:
    assert run(code) == expected


@pytest.mark.parametrize(
    ("code", "message"),
    [
        ("false && missing == 1", "Variable not found: missing"),
        ("y = 3", "use the operator [:=]"),
        ("1 +", "unexpected end"),
        ("3foo", "malformed number"),
        ("65.", "malformed number"),
        ("'open", "unterminated string"),
        ("s := 'ab'; -s", "Invalid operator [-] for std::string"),
        ("1 = 2", "needs a variable"),
    ],
)
def test_script_errors_are_clear(code: str, message: str) -> None:
    with pytest.raises(ScriptError, match=re.escape(message)):
        run(code)


def test_root_blackboard_is_reached_with_at() -> None:
    root = Blackboard()
    child = Blackboard(parent=root)
    compile_script("@g := 3; local := @g * 2")(ScriptEnv(child, {}))
    assert root.get("g") == 3 and child.get("local") == 6.0 and not root.has("local")


@pytest.mark.parametrize(
    ("text", "number"),
    [
        ("12abc", 12.0),
        ("  -3.5e1m", -35.0),
        ("+0x1p-2", 0.25),
        ("0x", 0.0),
        ("1e", 1.0),
        ("INF", float("inf")),
    ],
)
def test_text_reads_as_its_leading_number(text: str, number: float) -> None:
    assert text_to_double(text) == number


@pytest.mark.parametrize("text", ["", "a12", ".", "-", "1e999", "1e-400"])
def test_text_with_no_number_or_out_of_range_is_refused(text: str) -> None:
    # std::stod throws invalid_argument for the first four and out_of_range for the last two.
    with pytest.raises(ValueError, match="string to number"):
        text_to_double(text)


def test_a_double_entry_takes_text_by_its_leading_number() -> None:
    assert run("x := 1.5; x = ' 7 m'; x") == 7.0


def test_a_double_beyond_int64_does_not_wrap() -> None:
    # 2^63 itself wrapped to the smallest int64 in 4.8; 4.10 refuses it, as the engine does.
    with pytest.raises(ScriptError, match="Invalid floating point to integer conversion"):
        run("x := 2; x *= 4611686018427387904.0")
    assert run("x := 2; x *= 2305843009213693952.0; x") == 2**62


def test_a_long_chain_of_operators_costs_one_level_of_the_stack() -> None:
    # 20,000 terms, evaluated one operator at a time, left to right, as BT.CPP's AST does.
    board = Blackboard()
    terms = "+".join(["1"] * 10_000) + "-" + "-".join(["1"] * 9_999)
    assert compile_script(f"x := {terms}")(ScriptEnv(board, {})) == 1.0
    assert board.get("x") == 1.0
    assert compile_script("y := 2 * 3 + 4 * 5 - 6 / 2 .. 'a'")(ScriptEnv(board, {})) == "23.000000a"


@pytest.mark.parametrize(
    "nested",
    [
        lambda depth: "(" * depth + "1" + ")" * depth,
        lambda depth: "-" * depth + "1",
        lambda depth: "1 ? " * depth + "1" + " : 0" * depth,
    ],
    ids=["parentheses", "prefix operators", "ternaries"],
)
def test_a_script_nested_past_the_limit_is_refused_when_it_compiles(nested: object) -> None:
    from coral_core.bt.scripting.parser import MAX_NESTING

    make = nested  # type: ignore[assignment]
    compile_script(f"x := {make(MAX_NESTING - 1)}")  # type: ignore[operator]
    with pytest.raises(ScriptError, match=f"the script nests more than {MAX_NESTING} levels deep"):
        compile_script(f"x := {make(MAX_NESTING)}")  # type: ignore[operator]
