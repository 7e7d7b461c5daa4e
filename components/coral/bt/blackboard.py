"""Per-SubTree-instance blackboards with remapping, `_autoremap`, private keys, `@root` and sequence ids.

Built by the builder (one per SubTree instance, the main tree uses the root board); read by nodes'
ports and by scripts; `Tree.root_blackboard` exposes the root one to the executor.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from typing import Any

from coral.bt.errors import ScriptError
from coral.bt.ports import coerce_value, is_typed

EMPTY: Any = type("Empty", (), {"__repr__": lambda self: "<empty>"})()


class Entry:
    __slots__ = ("value", "type", "seq", "stamp")

    def __init__(self, type_name: str = "any", value: Any = EMPTY) -> None:
        self.value = value
        self.type = type_name
        self.seq = 0
        self.stamp = 0.0


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
        if key[:1] == "@":
            return self.root().create_entry(key[1:], type_name)
        entry = self.storage.get(key)
        if entry is not None:
            return entry
        parent = self.parent
        if parent is not None:
            target = self.remap.get(key)
            if target is not None:
                return parent.create_entry(target, type_name)
            if self.autoremap and key[:1] != "_":
                return parent.create_entry(key, type_name)
        entry = Entry(type_name)
        self.storage[key] = entry
        return entry

    def set(self, key: str, value: Any) -> None:
        entry = self.get_entry(key)
        if entry is None:
            entry = self.create_entry(key)
        self._write(key, entry, value)

    def _write(self, key: str, entry: Entry, value: Any) -> Any:
        if is_typed(entry.type) or entry.type == "string":
            try:
                value = coerce_value(value, entry.type, self.enums)
            except ValueError as err:
                raise ScriptError(f"blackboard entry [{key}] has type {entry.type}: {err}") from None
        entry.value = value
        entry.seq += 1
        entry.stamp = time.monotonic()
        return value

    def get(self, key: str, default: Any = None) -> Any:
        entry = self.get_entry(key)
        if entry is None or entry.value is EMPTY:
            return default
        return entry.value

    def has(self, key: str) -> bool:
        entry = self.get_entry(key)
        return entry is not None and entry.value is not EMPTY

    def unset(self, key: str) -> None:
        if key[:1] == "@":
            self.root().unset(key[1:])
            return
        if key in self.storage:
            del self.storage[key]
            return
        if self.parent is not None:
            target = self.remap.get(key)
            if target is not None:
                self.parent.unset(target)
            elif self.autoremap and key[:1] != "_":
                self.parent.unset(key)

    def keys(self) -> list[str]:
        return list(self.storage)

    def __iter__(self) -> Iterator[str]:
        return iter(list(self.storage))

    def as_dict(self) -> dict[str, Any]:
        return {k: e.value for k, e in self.storage.items() if e.value is not EMPTY}

    # scripting interface
    def script_read(self, key: str) -> Any:
        entry = self.get_entry(key)
        if entry is None:
            raise ScriptError(f"Variable not found: {key}")
        if entry.value is EMPTY:
            raise ScriptError(f"Variable [{key}] is not initialized")
        value = entry.value
        if isinstance(value, bool):
            return 1.0 if value else 0.0
        return value

    def script_write(self, key: str, value: Any, create: bool) -> Any:
        entry = self.get_entry(key)
        if entry is None:
            if not create:
                raise ScriptError(f"The blackboard entry [{key}] doesn't exist yet; use ':=' to create it")
            entry = self.create_entry(key)
        return self._write(key, entry, value)
