"""Port specifications and BT.CPP's literal conversions (convertFromString) for port values.

Used by the registry (declared ports), the builder (literal checks at load time), nodes'
get_input and the blackboard (converting strings written to typed entries).
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from coral_core import parsing
from coral_core.bt.anyvalue import (
    STOD_PREFIX,
    bool_cast,
    exact_double,
    std_to_string,
    text_to_double,
    to_int64,
)
from coral_core.bt.status import PortDirection, parse_status


@dataclass
class PortSpec:
    name: str
    direction: PortDirection = PortDirection.INPUT
    type: str = "any"
    default: str | None = None
    description: str = ""
    required: bool = False
    """The node cannot run without this port (BT.CPP finds out at the first tick; we at load time)."""


class DeclaredPort(Protocol):
    """A port as a behavior's declaration writes it (an image label, a plugin manifest): the direction
    by name; a description only where the declaration carries one."""

    @property
    def name(self) -> str: ...

    @property
    def direction(self) -> str: ...

    @property
    def type(self) -> str: ...

    @property
    def default(self) -> str | None: ...


def declared_ports(declared: Iterable[DeclaredPort]) -> list[PortSpec]:
    """The engine's specs of declared ports. None is required: a declaration names what a node
    accepts, and BT.CPP itself only finds a missing port when the node runs."""
    return [
        PortSpec(
            name=p.name,
            direction=PortDirection(p.direction),
            type=p.type,
            default=p.default,
            description=getattr(p, "description", ""),
        )
        for p in declared
    ]


# Every C++ integer type a port may name, with its width and whether it is signed: BT.CPP's own
# nodes have these widths (`fits_integer`), and all of them normalize to "int".
_CPP_INT_BITS = {
    "short": (16, True),
    "int": (32, True),
    "int32": (32, True),
    "int32_t": (32, True),
    "unsigned": (32, False),
    "unsigned int": (32, False),
    "uint": (32, False),
    "uint32": (32, False),
    "uint32_t": (32, False),
    "long": (64, True),
    "int64": (64, True),
    "int64_t": (64, True),
    "unsigned long": (64, False),
    "uint64": (64, False),
    "uint64_t": (64, False),
    "size_t": (64, False),
}
_FLOAT = {"double", "float"}
_STRING = {"string", "std::string", "str", "script"}
_BOOL = {"bool"}
_STATUS = {"nodestatus", "bt::nodestatus", "status"}


def normalize_type(type_name: str) -> str:
    """Maps C++/Python spellings onto: any, Any, string, int, double, bool, NodeStatus, list:<elem>
    (vectors), queue:<elem> (deques and SharedQueues, which Loop nodes consume in place), or itself."""
    t = (type_name or "any").strip()
    low = t.lower()
    if low in ("", "any", "anytypeallowed", "object"):
        return "any"
    if low == "bt::any":
        return "Any"
    if low in _STRING:
        return "string"
    if low in _CPP_INT_BITS:
        return "int"
    if low in _FLOAT:
        return "double"
    if low in _BOOL:
        return "bool"
    if low in _STATUS:
        return "NodeStatus"
    for prefix in ("std::vector<", "vector<", "list["):
        if low.startswith(prefix):
            return "list:" + normalize_type(t[len(prefix) :].rstrip(">]"))
    for prefix in ("std::deque<", "deque<", "bt::sharedqueue<", "sharedqueue<"):
        if low.startswith(prefix):
            return "queue:" + normalize_type(t[len(prefix) :].rstrip(">]"))
    return t


def is_unsigned(type_name: str) -> bool:
    """An unsigned C++ integer type, which "int" (every integer type's normalized name) does not say."""
    low = type_name.strip().lower()
    bits_signed = _CPP_INT_BITS.get(low)
    return bits_signed is not None and not bits_signed[1]


def fits_integer(value: int, type_name: str, cpp_widths: bool) -> bool:
    """Whether an integer literal fits a port of `type_name`. With `cpp_widths` (BT.CPP's own
    nodes) the C++ type's width counts; a plugin's `int` is Python's, unbounded, and only its
    unsigned types refuse a negative value."""
    bits_signed = _CPP_INT_BITS.get(type_name.strip().lower()) if cpp_widths else None
    if bits_signed is None:
        return not (is_unsigned(type_name) and value < 0)
    bits, signed = bits_signed
    low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
    return low <= value <= high


def element_type(type_name: str) -> str | None:
    """The element type of a declared container type (`std::deque<int>` gives `int`), else None."""
    text = type_name.strip()
    for opening, closing in (("<", ">"), ("[", "]")):
        start = text.find(opening)
        if start > 0 and text.endswith(closing):
            return text[start + 1 : -1].strip()
    return None


def literal_fits(value: Any, type_name: str, cpp_widths: bool) -> bool:
    """Whether a converted literal's integers fit the port's integer type, or its elements' (a
    LoopInt queue of `std::deque<int>`)."""
    if isinstance(value, int) and not isinstance(value, bool):
        return fits_integer(value, type_name, cpp_widths)
    inner = element_type(type_name)
    if inner is not None and isinstance(value, (list, deque)):
        return all(literal_fits(item, inner, cpp_widths) for item in value)
    return True


def is_typed(norm: str) -> bool:
    """Does a literal for this type need converting (and checking at load time)?"""
    return norm not in ("any", "Any", "string")


def convert_bool(text: str) -> bool:
    s = text.strip()
    if s in ("1", "true", "TRUE", "True"):
        return True
    if s in ("0", "false", "FALSE", "False"):
        return False
    raise ValueError(f"convertFromString(): invalid bool conversion of '{text}'")


# BT.CPP converts with std::from_chars (ints) and std::stod (doubles): both read the longest numeric
# prefix and ignore what follows, so "2.5" is the int 2 and "3 m" the double 3.0.
_INT_PREFIX = re.compile(r"-?[0-9]+")


def convert_int(text: str, enums: Mapping[str, int] | None = None) -> int:
    if enums:
        s = text.strip()
        if s in enums:
            return int(enums[s])
    m = _INT_PREFIX.match(text)
    if m is None:
        raise ValueError(f"Can't convert string [{text}] to integer")
    return int(m.group(0))


def convert_double(text: str) -> float:
    try:
        return text_to_double(text)
    except ValueError:
        raise ValueError(f"Can't convert string [{text}] to double (stod)") from None


def has_trailing_text(text: str, type_name: str) -> bool:
    """Would BT.CPP ignore part of this literal (a numeric prefix followed by more text)?"""
    pattern = _INT_PREFIX if type_name == "int" else STOD_PREFIX if type_name == "double" else None
    if pattern is None:
        return False
    m = pattern.match(text)
    return m is not None and text[m.end() :].strip() != ""


def convert_string(text: str, type_name: str, enums: Mapping[str, int] | None = None) -> Any:
    """Converts a literal string to `type_name` (already normalized); raises ValueError."""
    if type_name == "any" or type_name == "string" or type_name == "Any":
        return text
    if type_name == "int":
        return convert_int(text, enums)
    if type_name == "double":
        if enums and text.strip() in enums:
            return float(enums[text.strip()])
        return convert_double(text)
    if type_name == "bool":
        return convert_bool(text)
    if type_name == "NodeStatus":
        return parse_status(text)
    if type_name.startswith("queue:"):
        # BT.CPP's queue converter splits on ';' only: `json:` is a vector's, not a queue's.
        elem = type_name[6:]
        return deque(convert_string(part, elem, enums) for part in text.split(";")) if text else deque()
    if type_name.startswith("list:"):
        elem = type_name[5:]
        if text.startswith("json:"):
            data = parsing.load_json(text[5:])
            if not isinstance(data, list):
                raise ValueError(f"json literal '{text}' is not a list")
            return data
        if text == "":
            return []
        return [convert_string(part, elem, enums) for part in text.split(";")]
    if enums and text.strip() in enums:
        return enums[text.strip()]
    if ";" in text:
        return [_auto_number(p) for p in text.split(";")]
    return text


def _auto_number(part: str) -> Any:
    try:
        return int(part)
    except ValueError:
        try:
            return float(part)
        except ValueError:
            return part


def coerce_value(value: Any, type_name: str, enums: Mapping[str, int] | None = None) -> Any:
    """Makes a stored value fit a typed port (strings are parsed, integral doubles become ints)."""
    if type_name == "any" or type_name == "Any":
        return value
    if isinstance(value, str):
        return convert_string(value, type_name, enums)
    if type_name == "int":
        if isinstance(value, bool):
            return int(value)
        if isinstance(value, float):
            return to_int64(value)
        return value
    if type_name == "NodeStatus" and isinstance(value, (int, float)):
        # BT.CPP casts a number to the enum through int: a fraction is refused, and a number
        # outside the enum (which BT.CPP would return as a status and crash on) is refused here.
        status = to_int64(value) if isinstance(value, float) else int(value)
        if not 0 <= status <= 4:
            raise ValueError(
                f"{status} is no NodeStatus (0 IDLE, 1 RUNNING, 2 SUCCESS, 3 FAILURE, 4 SKIPPED)"
            )
        return status
    if type_name == "double" and isinstance(value, (int, bool)):
        return exact_double(value)
    if type_name == "bool" and isinstance(value, (int, float)):
        return bool_cast(value)
    if type_name == "string" and isinstance(value, (int, float)):
        return std_to_string(value)
    return value


def blackboard_key(raw: str) -> str | None:
    """Returns the key of a `{key}` pointer (trimmed), or None for a literal. `{=}`/`=` return '='."""
    s = raw.strip()
    if s == "=":
        return "="
    if len(s) >= 3 and s[0] == "{" and s[-1] == "}":
        return s[1:-1].strip()
    return None
