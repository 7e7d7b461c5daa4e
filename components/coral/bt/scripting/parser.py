"""Pratt parser of the scripting language; compiles a script into nested Python closures.

Used for Script/ScriptCondition/Precondition nodes, Switch/pre/post attributes (via the builder).
Precedence (low to high): assignment, ternary, ||, &&, chained comparisons, | ^, &, + - .., * /, prefix.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol

from coral.bt.errors import ScriptError
from coral.bt.scripting.tokenizer import Token, tokenize
from coral.bt.scripting.values import compare, num, to_int, to_text, truthy

Fn = Callable[["ScriptEnv"], Any]


class ScriptBoard(Protocol):
    def script_read(self, key: str) -> Any: ...
    def script_write(self, key: str, value: Any, create: bool) -> Any: ...


class ScriptEnv:
    """What a script sees: the node's blackboard and the enum registry (enums resolve first)."""

    __slots__ = ("board", "enums")

    def __init__(self, board: ScriptBoard, enums: Mapping[str, int]) -> None:
        self.board = board
        self.enums = enums


_COMPARISONS = {"==", "!=", "<", ">", "<=", ">="}
_ASSIGN = {":=", "=", "+=", "-=", "*=", "/="}
_BINARY_PREC = {"||": 3, "&&": 4, "|": 6, "^": 6, "&": 7, "+": 8, "-": 8, "..": 8, "*": 9, "/": 9}


class _Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens = tokenize(text)
        self.i = 0

    def peek(self) -> Token:
        return self.tokens[self.i]

    def next(self) -> Token:
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def fail(self, msg: str) -> ScriptError:
        return ScriptError(f"{msg} in script [{self.text}]")

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
        left = self.prefix()
        while True:
            tok = self.peek()
            if tok.kind != "op":
                return left
            op = str(tok.value)
            if op in _ASSIGN:
                raise self.fail(f"assignment '{op}' needs a variable on its left (position {tok.pos})")
            if op == "?" and min_prec <= 2:
                self.next()
                then = self.expression(1)
                self.expect(":")
                other = self.expression(2)
                left = _ternary(left, then, other)
                continue
            if op in _COMPARISONS and min_prec <= 5:
                operands = [left]
                ops: list[str] = []
                while self.peek().kind == "op" and self.peek().value in _COMPARISONS:
                    ops.append(str(self.next().value))
                    operands.append(self.expression(6))
                left = _chain(ops, operands)
                continue
            prec = _BINARY_PREC.get(op)
            if prec is None or prec < min_prec:
                return left
            self.next()
            right = self.expression(prec + 1)
            left = _binary(op, left, right)

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
            value = rhs(env)
            if name in env.enums:
                raise ScriptError(f"cannot assign to the enum '{name}'")
            return env.board.script_write(name, value, create)

        return assign
    arith = op[0]

    def compound(env: ScriptEnv) -> Any:
        value = rhs(env)
        current = env.board.script_read(name)
        if arith == "+" and isinstance(current, str) and isinstance(value, str):
            result: Any = current + value
        else:
            result = _arith(arith, current, value)
        return env.board.script_write(name, result, False)

    return compound


def _arith(op: str, a: Any, b: Any) -> Any:
    if op == "+":
        if isinstance(a, str) and isinstance(b, str):
            return a + b
        return num(a, op) + num(b, op)
    if op == "-":
        return num(a, op) - num(b, op)
    if op == "*":
        return num(a, op) * num(b, op)
    if op == "/":
        d = num(b, op)
        if d == 0:
            raise ScriptError("division by zero")
        return num(a, op) / d
    if op == "..":
        return to_text(a) + to_text(b)
    if op == "&":
        return float(to_int(a, op) & to_int(b, op))
    if op == "|":
        return float(to_int(a, op) | to_int(b, op))
    if op == "^":
        return float(to_int(a, op) ^ to_int(b, op))
    raise ScriptError(f"unknown operator '{op}'")


def _binary(op: str, left: Fn, right: Fn) -> Fn:
    if op == "&&":
        # Both sides are evaluated on purpose: BT.CPP's && and || do not short-circuit.
        def land(env: ScriptEnv) -> Any:
            a = truthy(left(env))
            b = truthy(right(env))
            return 1.0 if (a and b) else 0.0

        return land
    if op == "||":

        def lor(env: ScriptEnv) -> Any:
            a = truthy(left(env))
            b = truthy(right(env))
            return 1.0 if (a or b) else 0.0

        return lor
    return lambda env: _arith(op, left(env), right(env))


def _chain(ops: list[str], operands: list[Fn]) -> Fn:
    def run(env: ScriptEnv) -> Any:
        values = [f(env) for f in operands]
        for k, op in enumerate(ops):
            if not compare(op, values[k], values[k + 1], env.enums):
                return 0.0
        return 1.0

    return run


def _ternary(cond: Fn, then: Fn, other: Fn) -> Fn:
    return lambda env: then(env) if truthy(cond(env)) else other(env)


def _unary(op: str, operand: Fn) -> Fn:
    if op == "-":
        return lambda env: -num(operand(env), "-")
    if op == "!":
        return lambda env: 0.0 if truthy(operand(env)) else 1.0
    return lambda env: float(~to_int(operand(env), "~"))


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
