"""Value semantics of the scripting language: doubles, strings, comparisons, truthiness."""

from __future__ import annotations

from collections.abc import Mapping

from coral.bt.errors import ScriptError

EPSILON = 2.220446049250313e-16


def is_number(v: object) -> bool:
    return isinstance(v, (int, float))


def num(v: object, op: str) -> float:
    if isinstance(v, (int, float)):
        return float(v)
    raise ScriptError(f"operator '{op}' needs numbers, got {v!r}")


def to_int(v: object, op: str) -> int:
    f = num(v, op)
    if f != int(f):
        raise ScriptError(f"operator '{op}' needs integer values, got {v!r}")
    return int(f)


def truthy(v: object) -> bool:
    if isinstance(v, str):
        low = v.strip().lower()
        if low in ("true", "1"):
            return True
        if low in ("false", "0", ""):
            return False
        return True
    if isinstance(v, (int, float)):
        return v != 0
    return bool(v)


def string_to_number(s: str, enums: Mapping[str, int]) -> float:
    low = s.strip()
    if low in ("true", "TRUE", "True"):
        return 1.0
    if low in ("false", "FALSE", "False"):
        return 0.0
    if low in enums:
        return float(enums[low])
    try:
        return float(low)
    except ValueError:
        raise ScriptError(f"cannot compare string '{s}' with a number") from None


def compare(op: str, a: object, b: object, enums: Mapping[str, int]) -> bool:
    if isinstance(a, str) and isinstance(b, str):
        x: object = a
        y: object = b
    elif is_number(a) and is_number(b):
        x, y = float(a), float(b)  # type: ignore[arg-type]
        if op == "==":
            return abs(x - y) <= EPSILON  # type: ignore[operator]
        if op == "!=":
            return abs(x - y) > EPSILON  # type: ignore[operator]
    elif isinstance(a, str) and is_number(b):
        x, y = string_to_number(a, enums), float(b)  # type: ignore[arg-type]
    elif is_number(a) and isinstance(b, str):
        x, y = float(a), string_to_number(b, enums)  # type: ignore[arg-type]
    else:
        raise ScriptError(f"cannot compare {a!r} and {b!r}")
    if op == "==":
        return x == y
    if op == "!=":
        return x != y
    if op == "<":
        return x < y  # type: ignore[operator]
    if op == ">":
        return x > y  # type: ignore[operator]
    if op == "<=":
        return x <= y  # type: ignore[operator]
    return x >= y  # type: ignore[operator]


def to_text(v: object) -> str:
    if isinstance(v, float):
        return repr(int(v)) if v == int(v) and abs(v) < 1e15 else repr(v)
    return str(v)
