"""Per-SubTree-instance blackboards with BT.CPP's typed entries, remapping, `_autoremap`, private keys,
`@root` and sequence ids.

An entry has a declared type (from the port that created it, `any` for untyped ports and scripts,
`Any` for `BT::Any` ports) and a value with a type of its own; writes convert or refuse by BT.CPP's
rules (`Blackboard::set`, `Any::copyInto`, `ExprAssignment`). Built by the builder (one board per
SubTree instance); read by ports and scripts; `Tree.root_blackboard` exposes the root one.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from typing import Any

from coral_core.bt.anyvalue import EMPTY, UNTYPED, casting_is_safe, copy_into, is_number, kind_of, to_int64
from coral_core.bt.errors import ScriptError
from coral_core.bt.ports import convert_string
from coral_core.bt.scripting.values import string_to_number

__all__ = ["EMPTY", "Blackboard", "Entry", "parses_text", "strongly_typed"]


def strongly_typed(type_name: str) -> bool:
    return type_name not in UNTYPED


def parses_text(type_name: str) -> bool:
    """Does BT.CPP give an entry of this declared type a string converter? Untyped entries and
    enums (NodeStatus) have none, so text written into them by a script or SetBlackboard is refused."""
    return strongly_typed(type_name) and type_name != "NodeStatus"


class Entry:
    __slots__ = ("value", "type", "seq", "stamp", "cpp_type")

    def __init__(self, type_name: str = "any", value: Any = EMPTY) -> None:
        self.value = value
        self.type = type_name
        self.seq = 0
        self.stamp = 0.0
        # The C++ type of the built-in node's port that declared the entry (`int`, `unsigned`,
        # `std::deque<int>`): text written into it must fit that width (`ports.literal_fits`).
        self.cpp_type: str | None = None

    def touch(self) -> None:
        self.seq += 1
        self.stamp = time.monotonic()


class Blackboard:
    """Key/value store; `parent` plus `remap` (internal -> parent key) link a subtree to its caller."""

    def __init__(
        self,
        parent: Blackboard | None = None,
        autoremap: bool = False,
        enums: Mapping[str, int] | None = None,
    ) -> None:
        self.parent = parent
        self.autoremap = autoremap
        self.storage: dict[str, Entry] = {}
        self.remap: dict[str, str] = {}
        self.enums: Mapping[str, int] = enums if enums is not None else (parent.enums if parent else {})

    def root(self) -> Blackboard:
        bb = self
        while bb.parent is not None:
            bb = bb.parent
        return bb

    def get_entry(self, key: str) -> Entry | None:
        if key[:1] == "@":
            return self.root().get_entry(key[1:])
        entry = self.storage.get(key)
        if entry is not None:
            return entry
        parent = self.parent
        if parent is not None:
            target = self.remap.get(key)
            if target is not None:
                return parent.get_entry(target)
            if self.autoremap and key[:1] != "_":
                return parent.get_entry(key)
        return None

    def create_entry(self, key: str, type_name: str = "any") -> Entry:
        """`createEntry`: the existing entry (refusing a second strong type) or a new empty one,
        created where remapping or `_autoremap` points."""
        if key[:1] == "@":
            return self.root()._create(key[1:], type_name)
        return self._create(key, type_name)

    def _create(self, key: str, type_name: str) -> Entry:
        entry = self.storage.get(key)
        if entry is not None:
            if entry.type != type_name and strongly_typed(entry.type) and strongly_typed(type_name):
                raise ScriptError(
                    f"Blackboard entry [{key}]: once declared, the type of a port shall not change. "
                    f"Previously declared type [{entry.type}], current type [{type_name}]"
                )
            return entry
        parent = self.parent
        if parent is not None:
            target = self.remap.get(key)
            if target is not None:
                return parent._create(target, type_name)
            if self.autoremap and key[:1] != "_":
                return parent._create(key, type_name)
        entry = Entry(type_name)
        self.storage[key] = entry
        return entry

    def set(self, key: str, value: Any, port_type: str | None = None, value_type: str | None = None) -> None:
        """`Blackboard::set<T>` with T = `port_type` (default: the value's own type).

        `value_type` names the declared type a string was parsed into (a queue, say): BT.CPP's Any
        knows that type, a Python container does not.
        """
        if key[:1] == "@":
            self.root().set(key[1:], value, port_type, value_type)
            return
        own = value_type or kind_of(value)
        t = port_type if port_type is not None else own
        entry = self.storage.get(key)
        if entry is None:
            # A new (or remapped) entry is declared with the value's own type; a std::string
            # write declares an untyped one. The value is stored as it is.
            new_type = "any" if t == "string" else own if t == "Any" else t
            entry = self._create(key, new_type)
            entry.value = value
            entry.touch()
            return
        if not strongly_typed(entry.type):
            entry.type = t
            entry.value = value
            entry.touch()
            return
        declared = entry.type
        if declared != t and declared != own:
            converted = EMPTY
            # set<std::string> parses the text with the entry's converter; set<Any> does not.
            if isinstance(value, str) and t != "Any" and parses_text(declared):
                try:
                    converted = convert_string(value, declared, self.enums)
                except ValueError:
                    converted = EMPTY
            if converted is not EMPTY:
                value = converted
            elif not (t != "Any" and is_number(value) and casting_is_safe(declared, value)):
                raise ScriptError(
                    f"Blackboard::set({key}): once declared, the type of a port shall not change. "
                    f"Previously declared type [{declared}], current type [{t}]"
                )
        if t == "Any":
            entry.value = value
        else:
            try:
                entry.value = copy_into(entry.value, value)
            except ValueError as err:
                raise ScriptError(f"Blackboard::set({key}): {err}") from None  # BT.CPP: unwrapped
        entry.touch()

    def get(self, key: str, default: Any = None) -> Any:
        entry = self.get_entry(key)
        if entry is None or entry.value is EMPTY:
            return default
        return entry.value

    def has(self, key: str) -> bool:
        entry = self.get_entry(key)
        return entry is not None and entry.value is not EMPTY

    def unset(self, key: str) -> None:
        """Removes a local entry only: BT.CPP follows neither remapping nor `@` here."""
        self.storage.pop(key, None)

    def keys(self) -> list[str]:
        return list(self.storage)

    def __iter__(self) -> Iterator[str]:
        return iter(list(self.storage))

    def as_dict(self) -> dict[str, Any]:
        return {k: e.value for k, e in self.storage.items() if e.value is not EMPTY}

    # scripting interface ------------------------------------------------------------------
    def script_read(self, key: str) -> Any:
        """The value (EMPTY when the entry was declared but never written); a missing key throws."""
        entry = self.get_entry(key)
        if entry is None:
            raise ScriptError(f"Variable not found: {key}")
        value = entry.value
        if isinstance(value, bool):
            # BT.CPP's Any holds a bool as an int64: a script copies it on as the integer.
            return int(value)
        return value

    def script_entry(self, key: str, create: bool) -> Entry:
        """The entry an assignment writes; `:=` creates it before the right side is evaluated."""
        entry = self.get_entry(key)
        if entry is None:
            if not create:
                raise ScriptError(
                    f"The blackboard entry [{key}] doesn't exist, yet. If you want to create a new "
                    "one, use the operator [:=] instead of [=]"
                )
            entry = self.create_entry(key, "any")
        return entry

    def script_assign(self, key: str, entry: Entry, value: Any) -> Any:
        """`:=`/`=`: the first write to an untyped entry takes any value; a string converts through
        the declared type; otherwise `Any::copyInto` decides."""
        if value is EMPTY:
            raise ScriptError("The right operand of the operator [=] is not initialized")
        dst = entry.value
        if dst is EMPTY and entry.type == "any":
            entry.value = value
        elif isinstance(value, str) and not isinstance(dst, str):
            if parses_text(entry.type):
                try:
                    entry.value = convert_string(value, entry.type, self.enums)
                except ValueError as err:
                    raise ScriptError(f"Error assigning a value to entry [{key}]: {err}") from None
            elif entry.type == "Any":
                raise ScriptError("BT.CPP has no convertFromString for BT::Any: a string can't be stored")
            elif is_number(dst):
                entry.value = string_to_number(value, self.enums)
            else:
                raise ScriptError(
                    f"Error assigning a value to entry [{key}] with type [{entry.type}]. The right "
                    "operand is a string, can't convert to it"
                )
        else:
            try:
                entry.value = copy_into(dst, value)
            except ValueError:
                raise ScriptError(
                    f"Error assigning a value to entry [{key}]: the right operand has type "
                    f"[{kind_of(value)}] and can't be converted to [{kind_of(dst)}]"
                ) from None
        entry.touch()
        return entry.value

    def script_store(self, key: str, entry: Entry, value: Any) -> Any:
        """Result of a compound assignment (`+=` ...): converted into the entry's current kind."""
        try:
            dst = entry.value
            if isinstance(dst, int) and not isinstance(dst, bool) and isinstance(value, float):
                entry.value = to_int64(value)
            else:
                entry.value = copy_into(dst, value)
        except ValueError as err:
            raise ScriptError(f"Error assigning a value to entry [{key}]: {err}") from None
        entry.touch()
        return entry.value
