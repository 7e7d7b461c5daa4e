"""Pratt parser of the scripting language; compiles a script into nested Python closures.

Used for Script/ScriptCondition/Precondition nodes, Switch/pre/post attributes (via the builder).
Precedence (low to high): assignment, ternary, ||, &&, chained comparisons, | ^, &, + - .., * /, prefix.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from coral_core.bt.anyvalue import EMPTY, bool_cast, is_number, kind_of, std_to_string
from coral_core.bt.errors import ScriptError
from coral_core.bt.scripting.tokenizer import Token, tokenize
from coral_core.bt.scripting.values import (
    as_double,
    compare,
    condition_holds,
    ieee_divide,
    not_initialized,
    to_int,
)

Fn = Callable[["ScriptEnv"], Any]


class ScriptBoard(Protocol):
    def script_read(self, key: str) -> Any: ...
    def script_entry(self, key: str, create: bool) -> Any: ...
    def script_assign(self, key: str, entry: Any, value: Any) -> Any: ...
    def script_store(self, key: str, entry: Any, value: Any) -> Any: ...


class ScriptEnv:
    """What a script sees: the node's blackboard and the enum registry (enums resolve first)."""

    __slots__ = ("board", "enums")

    def __init__(self, board: ScriptBoard, enums: Mapping[str, int]) -> None:
        self.board = board
        self.enums = enums


# How deep a script may nest (parentheses, prefix operators, right operands, `?:`). BT.CPP's parser
# has limits of its own (1,024 parentheses; 255 prefix operators in a row); the engine parses and
# evaluates recursively, on the stack that also holds the tree's own nesting, so it refuses a
# script past this depth when the tree loads instead of overflowing the stack at a tick.
MAX_NESTING = 128
_COMPARISONS = {"==", "!=", "<", ">", "<=", ">="}
_ASSIGN = {":=", "=", "+=", "-=", "*=", "/="}
_BINARY_PREC = {"||": 3, "&&": 4, "|": 6, "^": 6, "&": 7, "+": 8, "-": 8, "..": 8, "*": 9, "/": 9}


class _Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens = tokenize(text)
        self.i = 0
        self.nesting = 0

    def peek(self) -> Token:
        return self.tokens[self.i]

    def next(self) -> Token:
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def fail(self, msg: str) -> ScriptError:
        # A generated script can be hundreds of kilobytes; the message names where, not all of it.
        shown = self.text if len(self.text) <= 200 else self.text[:200] + "..."
        return ScriptError(f"{msg} in script [{shown}]")

    def expect(self, op: str) -> None:
        tok = self.next()
        if tok.kind != "op" or tok.value != op:
            raise self.fail(f"expected '{op}' at position {tok.pos}")

    def program(self) -> list[Fn]:
        stmts: list[Fn] = []
        while True:
            while self.peek().kind == "op" and self.peek().value == ";":
                self.next()
            if self.peek().kind == "end":
                return stmts
            stmts.append(self.statement())
            tok = self.peek()
            if tok.kind != "end" and not (tok.kind == "op" and tok.value == ";"):
                raise self.fail(f"unexpected '{tok.value}' at position {tok.pos}")

    def statement(self) -> Fn:
        tok = self.peek()
        nxt = self.tokens[self.i + 1]
        if tok.kind == "id" and nxt.kind == "op" and nxt.value in _ASSIGN:
            self.next()
            self.next()
            rhs = self.expression(1)
            return _assignment(str(tok.value), str(nxt.value), rhs)
        return self.expression(1)

    def expression(self, min_prec: int) -> Fn:
        self.nesting += 1
        if self.nesting > MAX_NESTING:
            raise self.fail(
                f"the script nests more than {MAX_NESTING} levels deep (parentheses, operators, ?:) "
                f"at position {self.peek().pos}"
            )
        try:
            left = self.prefix()
            # Operators of this level apply left to right: `a + b - c * d` is one fold over
            # [(+, b), (-, c * d)], so a long chain costs one level of the stack, not one per operator.
            steps: list[tuple[str, Fn]] = []
            while True:
                tok = self.peek()
                if tok.kind != "op":
                    return _fold(left, steps)
                op = str(tok.value)
                if op in _ASSIGN:
                    raise self.fail(f"assignment '{op}' needs a variable on its left (position {tok.pos})")
                if op == "?" and min_prec <= 2:
                    self.next()
                    then = self.expression(1)
                    self.expect(":")
                    other = self.expression(2)
                    left, steps = _ternary(_fold(left, steps), then, other), []
                    continue
                if op in _COMPARISONS and min_prec <= 5:
                    operands = [_fold(left, steps)]
                    ops: list[str] = []
                    while self.peek().kind == "op" and self.peek().value in _COMPARISONS:
                        ops.append(str(self.next().value))
                        operands.append(self.expression(6))
                    left, steps = _chain(ops, operands), []
                    continue
                prec = _BINARY_PREC.get(op)
                if prec is None or prec < min_prec:
                    return _fold(left, steps)
                self.next()
                steps.append((op, self.expression(prec + 1)))
        finally:
            self.nesting -= 1

    def _signed_number(self, plus: Token) -> bool:
        # BT.CPP has no unary plus: a '+' written against a decimal number is that number's sign
        # (`+3`, `2 ++3`), while `+ 3`, `+x`, `+0x10` and `++3` do not parse.
        following = self.peek()
        at = following.pos
        return (
            following.kind == "num"
            and at == plus.pos + 1
            and self.text[at].isdigit()
            and self.text[at : at + 2].lower() != "0x"
        )

    def prefix(self) -> Fn:
        tok = self.next()
        if tok.kind == "num" or tok.kind == "str":
            value = tok.value
            return lambda env: value
        if tok.kind == "id":
            return _identifier(str(tok.value))
        if tok.kind == "op":
            if tok.value == "(":
                inner = self.expression(1)
                self.expect(")")
                return inner
            if tok.value == "+" and self._signed_number(tok):
                value = self.next().value
                return lambda env: value
            if tok.value in ("-", "!", "~"):
                operand = self.expression(10)
                return _unary(str(tok.value), operand)
        where = "end of script" if tok.kind == "end" else f"'{tok.value}' at position {tok.pos}"
        raise self.fail(f"unexpected {where}")


def _identifier(name: str) -> Fn:
    def read(env: ScriptEnv) -> Any:
        enums = env.enums
        if name in enums:
            return float(enums[name])
        return env.board.script_read(name)

    return read


def _assignment(name: str, op: str, rhs: Fn) -> Fn:
    if op == ":=" or op == "=":
        create = op == ":="

        def assign(env: ScriptEnv) -> Any:
            if name in env.enums:
                raise ScriptError(f"cannot assign to the enum '{name}'")
            # BT.CPP creates the entry before it evaluates the right side.
            entry = env.board.script_entry(name, create)
            value = rhs(env)
            if value is EMPTY:
                raise ScriptError(not_initialized("right", op))
            return env.board.script_assign(name, entry, value)

        return assign
    arith = op[0]

    def compound(env: ScriptEnv) -> Any:
        entry = env.board.script_entry(name, False)
        value = rhs(env)
        if value is EMPTY:
            raise ScriptError(not_initialized("right", op))
        current = entry.value
        if current is EMPTY:
            raise ScriptError(not_initialized("left", op))
        if isinstance(current, bool):
            current = float(current)
        if is_number(value):
            if not is_number(current):
                raise ScriptError("This Assignment operator can't be used with a non-numeric type")
            result: Any = _numeric(arith, as_double(current), as_double(value))
        elif isinstance(value, str):
            if arith != "+":
                raise ScriptError("Operator not supported for strings")
            result = std_to_string(current) + value
        else:
            result = current
        return env.board.script_store(name, entry, result)

    return compound


def _numeric(op: str, a: float, b: float) -> float:
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    return ieee_divide(a, b)


_NUMBER = (int, float)


def _arith(op: str, a: Any, b: Any) -> Any:
    if a is EMPTY:
        raise ScriptError(not_initialized("left", op))
    if b is EMPTY:
        raise ScriptError(not_initialized("right", op))
    if isinstance(a, _NUMBER) and isinstance(b, _NUMBER):
        # BT.CPP reads both as doubles before it looks at the operator, whichever it is.
        x, y = as_double(a), as_double(b)
        if op in ("+", "-", "*", "/"):
            return _numeric(op, x, y)
        if op in ("&", "|", "^"):
            i, j = to_int(a, op), to_int(b, op)
            return float(i & j if op == "&" else i | j if op == "|" else i ^ j)
        if op == "&&" or op == "||":
            try:
                p, q = bool_cast(a), bool_cast(b)
            except ValueError:
                raise ScriptError(
                    "Logic operators are not allowed if one of the operands is not castable to bool "
                    f"({std_to_string(a)} {op} {std_to_string(b)})"
                ) from None
            return 1.0 if (p and q if op == "&&" else p or q) else 0.0
        # `..` between two numbers falls through BT.CPP's operator to an empty result.
        return EMPTY
    elif isinstance(a, str) and isinstance(b, str) and op == "+":
        return a + b
    elif (
        op == ".."
        and (isinstance(a, str) or isinstance(b, str))
        and (isinstance(a, str) or is_number(a))
        and (isinstance(b, str) or is_number(b))
    ):
        return std_to_string(a) + std_to_string(b)
    raise ScriptError(f"Operation not permitted: [{op}] between {kind_of(a)} and {kind_of(b)}")


def _fold(first: Fn, steps: list[tuple[str, Fn]]) -> Fn:
    """Left-associative binary operators in order: `((first op1 a) op2 b) ...`."""
    if not steps:
        return first
    if len(steps) == 1:
        ((op, right),) = steps
        # Both sides are always evaluated: BT.CPP's && and || do not short-circuit.
        return lambda env: _arith(op, first(env), right(env))

    def run(env: ScriptEnv) -> Any:
        value = first(env)
        for op, operand in steps:
            value = _arith(op, value, operand(env))
        return value

    return run


def _chain(ops: list[str], operands: list[Fn]) -> Fn:
    def run(env: ScriptEnv) -> Any:
        # Pairwise, and the first false pair ends the chain before later operands are evaluated.
        lhs = operands[0](env)
        for k, op in enumerate(ops):
            rhs = operands[k + 1](env)
            if lhs is EMPTY:
                raise ScriptError(not_initialized("left", op))
            if rhs is EMPTY:
                raise ScriptError(not_initialized("right", op))
            if not compare(op, lhs, rhs, env.enums):
                return 0.0
            lhs = rhs
        return 1.0

    return run


def _ternary(cond: Fn, then: Fn, other: Fn) -> Fn:
    return lambda env: then(env) if condition_holds(cond(env)) else other(env)


def _unary(op: str, operand: Fn) -> Fn:
    def run(env: ScriptEnv) -> Any:
        value = operand(env)
        if is_number(value):
            v = as_double(value)
            if op == "-":
                return -v
            if op == "!":
                return 0.0 if v != 0 else 1.0
            if v > 2.0**63 or v < -(2.0**63):
                raise ScriptError("Number out of range for bitwise operation")
            # BT.CPP's range check lets NaN and 2^63 through to a cast that gives INT64_MIN on x86.
            whole = -(2**63) if math.isnan(v) or v == 2.0**63 else int(v)
            return float(~whole)
        if isinstance(value, str):
            raise ScriptError(f"Invalid operator [{op}] for std::string")
        raise ScriptError(f"ExprUnaryArithmetic: undefined (the operand of [{op}] is not initialized)")

    return run


def compile_condition(text: str) -> Callable[[ScriptEnv], Any]:
    """A pre- or post-condition attribute (`_skipIf`, `_post`, ...): BT.CPP refuses a blank one
    when the tree loads."""
    if not text.strip():
        raise ScriptError(f'Error in the script "{text}": Empty Script')
    return compile_script(text)


def compile_script(text: str) -> Callable[[ScriptEnv], Any]:
    """Parses `text` once; the returned function runs every statement and returns the last value."""
    stmts = _Parser(text).program()
    if not stmts:
        return lambda env: None
    if len(stmts) == 1:
        return stmts[0]

    def run_all(env: ScriptEnv) -> Any:
        value = None
        for s in stmts:
            value = s(env)
        return value

    return run_all
