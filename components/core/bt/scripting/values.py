"""Value semantics of the scripting language (BT.CPP's operators): numbers, strings, comparisons,
IEEE division and truthiness. Used by the parser and by nodes that turn a script result into a status."""

from __future__ import annotations

import math
from collections.abc import Mapping

from coral_core.bt.anyvalue import (
    EMPTY,
    bool_cast,
    exact_double,
    is_number,
    kind_of,
    text_to_double,
    to_int64,
)
from coral_core.bt.errors import BTRuntimeError, ScriptError

# BT.CPP compares doubles within float (not double) epsilon.
EPSILON = 1.1920928955078125e-07


def not_initialized(side: str, op: str) -> str:
    return f"The {side} operand of the operator [{op}] is not initialized"


def ieee_divide(a: float, b: float) -> float:
    """C++ double division: x/0 is +-inf and 0/0 is NaN (negative on x86, as std::to_string shows)."""
    if b != 0:
        return a / b
    if a == 0 or math.isnan(a):
        return -math.nan
    negative = (a < 0) != (math.copysign(1.0, b) < 0)
    return -math.inf if negative else math.inf


def as_double(v: object) -> float:
    """A number as a script's operators read it: BT.CPP's checked cast to double."""
    try:
        return exact_double(v)
    except ValueError as err:
        raise ScriptError(str(err)) from None


def to_int(v: object, op: str) -> int:
    """An operand of a bitwise operator: an int as it is, a double only when it is a whole int64."""
    if not is_number(v):
        raise ScriptError(f"operator '{op}' needs numbers, got {v!r}")
    if isinstance(v, int):
        return int(v)
    try:
        return to_int64(v)  # type: ignore[arg-type]
    except ValueError:
        raise ScriptError(
            "Binary operators are not allowed if one of the operands is not an integer"
        ) from None


def truthy(v: object) -> bool:
    """A script result read as a condition (ScriptCondition, Precondition, pre-condition attributes).

    A tree that relies on a text or a count being "truthy" stops with BT.CPP's error, plus what the
    value was, instead of running on.
    """
    try:
        return bool_cast(v)
    except ValueError as err:
        shown = f"the text {v!r}" if isinstance(v, str) else "empty" if v is EMPTY else repr(v)
        raise BTRuntimeError(f"{err} (the condition's value is {shown}; compare it, e.g. `x != 0`)") from None


def condition_holds(v: object) -> bool:
    """Ternary `c ? a : b`: BT.CPP reads the condition as a double, so text must start with a
    number (`'0'` is false, `'a'` an error) and any number other than zero holds."""
    if isinstance(v, str):
        try:
            return text_to_double(v) != 0.0
        except ValueError as err:
            raise ScriptError(str(err)) from None
    if is_number(v):
        return as_double(v) != 0.0
    raise ScriptError("Any::cast failed because it is empty")


def string_to_number(s: str, enums: Mapping[str, int]) -> float:
    """BT.CPP's `StringToDouble`: true, false and enum names, else the text's leading number."""
    if s == "true":
        return 1.0
    if s == "false":
        return 0.0
    if s in enums:
        return float(enums[s])
    try:
        return text_to_double(s)
    except ValueError as err:
        raise ScriptError(str(err)) from None


def compare(op: str, a: object, b: object, enums: Mapping[str, int]) -> bool:
    if isinstance(a, str) and isinstance(b, str):
        x: object = a
        y: object = b
    else:
        if isinstance(a, (int, float)) and isinstance(b, (int, float)):
            x, y = as_double(a), as_double(b)
        elif isinstance(a, str) and is_number(b):
            x, y = string_to_number(a, enums), as_double(b)
        elif is_number(a) and isinstance(b, str):
            x, y = as_double(a), string_to_number(b, enums)
        else:
            raise ScriptError(
                "Can't mix different types in Comparison. "
                f"Left operand [{kind_of(a)}] right operand [{kind_of(b)}]"
            )
        if op == "==":
            return abs(x - y) <= EPSILON  # type: ignore[operator]
        if op == "!=":
            return not abs(x - y) <= EPSILON  # type: ignore[operator]
    if op == "==":
        return x == y
    if op == "!=":
        return x != y
    # BT.CPP fails each ordering by its opposite (`<` fails when `>=` holds), so a NaN passes all.
    if op == "<":
        return not x >= y  # type: ignore[operator]
    if op == ">":
        return not x <= y  # type: ignore[operator]
    if op == "<=":
        return not x > y  # type: ignore[operator]
    return not x < y  # type: ignore[operator]
