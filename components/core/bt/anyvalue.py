"""BT.CPP's `BT::Any` rules for blackboard values: which kind a value has, how `copyInto` converts
between kinds, and how `std::to_string` prints numbers.

Python values stand for BT.CPP's: `int` (and `bool`) for int64, `float` for double, `str` for
strings, anything else for a user type. Used by the blackboard, port access and the scripting values.
"""

from __future__ import annotations

import math
import re
from numbers import Integral, Real
from typing import Any

EMPTY: Any = type("Empty", (), {"__repr__": lambda self: "<empty>", "__bool__": lambda self: False})()

# Declared entry types that are not "strongly typed" in BT.CPP: `any` is AnyTypeAllowed (untyped
# ports and script-created entries), `Any` is a `BT::Any` port (SkipUnlessUpdated's `entry`, ...).
UNTYPED = frozenset({"any", "Any"})


def kind_of(value: Any) -> str:
    """The entry type a value has of its own (what BT.CPP's `Any::type()` would report)."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "double"
    if isinstance(value, str):
        return "string"
    return type(value).__name__


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float))


def std_to_string(value: Any) -> str:
    """`std::to_string` for numbers (six decimals for doubles), the text itself for strings."""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "-nan" if math.copysign(1.0, value) < 0 else "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return f"{value:f}"
    return str(value)


# What `std::stod` reads at the start of a text: blanks, a sign, then inf/nan, a hex float or a
# decimal; the rest of the text is ignored.
STOD_PREFIX = re.compile(
    r"[ \t\n\v\f\r]*([+-]?(?:inf(?:inity)?|nan(?:\([0-9a-z_]*\))?"
    r"|0x(?:[0-9a-f]+\.?[0-9a-f]*|\.[0-9a-f]+)(?:p[+-]?[0-9]+)?"
    r"|(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:e[+-]?[0-9]+)?))",
    re.IGNORECASE,
)
_SMALLEST_NORMAL = 2.2250738585072014e-308


def text_to_double(text: str) -> float:
    """`Any::cast<double>()` of text, as the BT.CPP build the tests run against does it: `std::stod`,
    which reads a leading number and ignores what follows (`"12abc"` is 12, `" +5"` is 5, `"0x1F"` is
    31). Raises ValueError when no number starts the text, or when it is out of double's range."""
    m = STOD_PREFIX.match(text)
    if m is None:
        raise ValueError("Any failed string to number conversion")
    number = m.group(1)
    body = number.lstrip("+-").lower()
    if body.startswith(("inf", "nan")):
        value = math.nan if body.startswith("nan") else math.inf
        return -value if number.startswith("-") else value
    if body.startswith("0x"):
        value, mantissa = float.fromhex(number), body[2:].split("p")[0]
    else:
        value, mantissa = float(number), body.split("e")[0]
    # stod throws out_of_range where strtod reports ERANGE: overflow, and underflow (a nonzero
    # number that became zero or subnormal).
    underflow = abs(value) < _SMALLEST_NORMAL and mantissa.strip("0.") != ""
    if math.isinf(value) or underflow:
        raise ValueError("Any failed string to number conversion")
    return value


def bool_cast(v: object) -> bool:
    """BT.CPP's `Any::cast<bool>()`, which refuses more than it accepts: text of any kind, a
    negative number, and an integer other than 0 or 1 (an integer literal or an int entry;
    arithmetic yields doubles, which any non-negative value turns into a bool). Raises ValueError
    with BT.CPP's message."""
    if isinstance(v, bool):
        return v
    if v is EMPTY:
        raise ValueError("Any::cast failed because it is empty")
    if isinstance(v, str):
        raise ValueError("[Any::convert]: no known safe conversion between [std::string] and [bool]")
    if isinstance(v, Integral):
        if v < 0:
            raise ValueError("Value is negative and can't be converted to unsigned")
        if v > 1:
            raise ValueError("Implicit casting to bool is not allowed")
        return v == 1
    if isinstance(v, Real):
        if v < 0:
            raise ValueError("Value is negative and can't be converted to unsigned")
        return v != 0.0
    raise ValueError(f"[Any::convert]: no known safe conversion between [{kind_of(v)}] and [bool]")


# BT.CPP refuses to widen an int64 beyond 2^53 - 1 into a double ("Loss of precision"). Its check
# takes std::abs of the int, which leaves the smallest int64 negative, so that one passes.
_MAX_EXACT_INT = 2**53 - 1
_INT64_MIN = -(2**63)


def exact_double(value: Any) -> float:
    """BT.CPP's checked `Any::cast<double>()` of a number: an int that a double cannot hold
    exactly is refused (ValueError with BT.CPP's message)."""
    if type(value) is int and not -_MAX_EXACT_INT <= value <= _MAX_EXACT_INT and value != _INT64_MIN:
        raise ValueError(
            f"Loss of precision when converting a large integer number to floating point:{value}"
        )
    return float(value)


def to_int64(value: float) -> int:
    """BT.CPP's checked double -> int64 conversion: only integral values in int64's range convert
    (2^63 included, as 4.10 fixed: 4.8 let it wrap to the smallest int64)."""
    if not math.isfinite(value) or value != int(value) or not -(2.0**63) <= value < 2.0**63:
        raise ValueError(f"Invalid floating point to integer conversion of {std_to_string(value)}")
    return int(value)


def copy_into(dst: Any, value: Any) -> Any:
    """`Any::copyInto`: an empty destination takes the value as it is; numbers convert to the
    destination's kind (int64 refuses a non-integral double); strings only replace strings."""
    dst_type = type(dst)
    if dst_type is type(value) or dst is EMPTY:
        return value
    # The common script case first: an arithmetic result (double) into an int64 entry.
    if dst_type is int and type(value) is float:
        return to_int64(value)
    if not _builtin_kind(dst) and not _builtin_kind(value):
        # Two user types: a Python behavior's output of one declared type may take several Python
        # types (None, dict, a message); BT.CPP's C++ port always writes the same T.
        return value
    if kind_of(dst) == kind_of(value) or (isinstance(dst, str) and isinstance(value, str)):
        return value
    if is_number(dst) and is_number(value):
        if isinstance(dst, float):
            return exact_double(value)
        if isinstance(value, float):
            return to_int64(value)
        return int(value)
    raise ValueError(f"Any::copyInto fails: [{kind_of(value)}] into [{kind_of(dst)}]")


def _builtin_kind(value: Any) -> bool:
    return isinstance(value, (int, float, str))


def casting_is_safe(declared: str, value: Any) -> bool:
    """`isCastingSafe`: may a number be stored in an entry declared with another numeric type?"""
    if not is_number(value):
        return False
    if declared == "int" or declared == "bool":
        return not isinstance(value, float) or (math.isfinite(value) and value == int(value))
    return declared == "double"
