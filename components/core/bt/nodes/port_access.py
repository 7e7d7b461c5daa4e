"""Port access for nodes: `get_input`/`require_input`/`set_output` with BT.CPP's remapping rules
(`{key}`, `{=}`, literals converted to the declared port type, defaults from the port spec)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from coral_core.bt.anyvalue import kind_of
from coral_core.bt.blackboard import EMPTY
from coral_core.bt.errors import BTRuntimeError, ScriptError
from coral_core.bt.ports import (
    blackboard_key,
    coerce_value,
    convert_string,
    fits_integer,
    is_unsigned,
    normalize_type,
)

if TYPE_CHECKING:
    from coral_core.bt.blackboard import Blackboard
    from coral_core.bt.ports import PortSpec
    from coral_core.bt.runtime import Runtime

MISSING: Any = object()


class PortAccess:
    """Mixin of TreeNode; expects ports, port_specs, board, rt, path and _port_cache attributes."""

    ports: dict[str, str]
    port_specs: dict[str, PortSpec]
    board: Blackboard
    rt: Runtime
    path: str
    cpp_widths: bool
    _port_cache: dict[str, tuple[str | None, Any, str]]

    def _port(self, name: str) -> tuple[str | None, Any, str]:
        cached = self._port_cache.get(name)
        if cached is not None:
            return cached
        spec = self.port_specs.get(name)
        raw = self.ports.get(name)
        if raw is None and spec is not None:
            raw = spec.default
        type_name = normalize_type(spec.type) if spec is not None else "any"
        if raw is None:
            result: tuple[str | None, Any, str] = (None, MISSING, type_name)
        else:
            key = blackboard_key(raw)
            if key == "=":
                key = name
            if key is not None:
                result = (key, None, type_name)
            else:
                try:
                    value = convert_string(raw, type_name, self.rt.enums)
                except ValueError as err:
                    raise BTRuntimeError(f"Missing parameter [{name}]: {err}", node_path=self.path) from None
                result = (None, value, type_name)
        self._port_cache[name] = result
        return result

    def has_port_value(self, name: str) -> bool:
        return self._port(name)[1] is not MISSING

    def get_input(self, name: str, default: Any = None) -> Any:
        """The port value converted to the port type, or `default` when absent/uninitialised."""
        key, value, type_name = self._port(name)
        if key is None:
            return default if value is MISSING else value
        entry = self.board.get_entry(key)
        if entry is None or entry.value is EMPTY:
            return default
        if type_name == "any":
            return entry.value
        try:
            value = coerce_value(entry.value, type_name, self.rt.enums)
        except ValueError as err:
            raise BTRuntimeError(f"Missing parameter [{name}]: {err}", node_path=self.path) from None
        if type_name == "int" and isinstance(value, int) and not isinstance(value, bool):
            # "int" stands for every integer type; the port's own type refuses what BT.CPP's cast does.
            spec = self.port_specs.get(name)
            if spec is not None and not fits_integer(value, spec.type, self.cpp_widths):
                reason = (
                    "Value is negative and can't be converted to unsigned"
                    if value < 0 and is_unsigned(spec.type)
                    else f"Value out of bound when converting to {spec.type}"
                )
                raise BTRuntimeError(
                    f"Missing parameter [{name}]: {reason} (the entry [{key}] holds {value})",
                    node_path=self.path,
                )
        return value

    def require_input(self, name: str) -> Any:
        value = self.get_input(name, MISSING)
        if value is MISSING:
            key = self._port(name)[0]
            detail = f"blackboard entry [{key}] is not set" if key else "no value and no default"
            raise BTRuntimeError(f"Missing parameter [{name}]: {detail}", node_path=self.path)
        return value

    def set_output(self, name: str, value: Any) -> bool:
        """Writes the port's blackboard entry; False when the tree left this output unwired.

        BT.CPP's `setOutput` answers an unwired port with an error value that callers usually
        ignore, so a behavior may offer outputs a tree does not use. A name the node never
        declared is a programming error and raises.
        """
        raw = self.ports.get(name)
        spec = self.port_specs.get(name)
        if raw is None and spec is None:
            raise BTRuntimeError(f"[{name}] is not a declared port of this node", node_path=self.path)
        if raw is None and spec is not None:
            raw = spec.default
        key = blackboard_key(raw) if raw is not None else None
        if key == "=":
            key = name
        if key is None:
            return False
        port_type = normalize_type(spec.type) if spec is not None else kind_of(value)
        try:
            # BT.CPP's setOutput<T> takes a T: a Python value is first made one.
            value = coerce_value(value, port_type, self.rt.enums)
        except ValueError as err:
            raise BTRuntimeError(f"output port [{name}]: {err}", node_path=self.path) from None
        try:
            self.board.set(key, value, port_type)
        except ScriptError as err:
            raise BTRuntimeError(err.message, node_path=self.path) from None
        return True
