"""Built-in leaves: AlwaysSuccess/Failure, Script, ScriptCondition, SetBlackboard, UnsetBlackboard,
Sleep and WasEntryUpdated, with BT.CPP 4 semantics; registered by the registry."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from coral_core.bt.blackboard import EMPTY, parses_text, strongly_typed
from coral_core.bt.errors import BTLoadError, BTRuntimeError, ScriptError
from coral_core.bt.leaves import ConditionNode, StatefulAction, SyncAction
from coral_core.bt.nodes.base import NodeConfig
from coral_core.bt.nodes.board_decorators import entry_key
from coral_core.bt.ports import PortSpec, blackboard_key, convert_string, literal_fits
from coral_core.bt.runtime import Timer
from coral_core.bt.scripting import compile_script
from coral_core.bt.scripting.values import truthy
from coral_core.bt.status import FAILURE, RUNNING, SUCCESS, PortDirection


class AlwaysSuccess(SyncAction):
    def tick(self) -> int:  # type: ignore[override]
        return SUCCESS


class AlwaysFailure(SyncAction):
    def tick(self) -> int:  # type: ignore[override]
        return FAILURE


def _load_error(config: NodeConfig, message: str) -> BTLoadError:
    return BTLoadError(message, file=config.file, line=config.line, node_path=config.path)


def _compile_code(node: Any, config: NodeConfig) -> Callable[[], Any]:
    """The node's [code] script, compiled once at load time (a bad one is a load error), as a call
    that runs it on the node's blackboard and attributes a script error to the node."""
    raw = config.ports.get("code")
    if raw is None:
        raise _load_error(config, f"{config.node_id} needs the port [code]")
    try:
        script = compile_script(raw)
    except ScriptError as err:
        raise _load_error(config, f"invalid script in [code]: {err.message}") from None

    def run() -> Any:
        try:
            return script(node._env)
        except ScriptError as err:
            raise BTRuntimeError(f"Error in script [{raw}]: {err.message}", node_path=node.path) from None

    return run


class Script(SyncAction):
    """Runs `code`; always SUCCESS. A script error aborts the tick with a BTRuntimeError."""

    PORTS = [PortSpec("code", type="string", required=True, description="Piece of code that can be parsed")]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self._run_code = _compile_code(self, config)

    def tick(self) -> int:  # type: ignore[override]
        self._run_code()
        return SUCCESS


class ScriptCondition(ConditionNode):
    PORTS = [
        PortSpec(
            "code",
            type="string",
            required=True,
            description="Piece of code that can be parsed. Must return false or true",
        )
    ]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self._run_code = _compile_code(self, config)

    def tick(self) -> int:  # type: ignore[override]
        return SUCCESS if truthy(self._run_code()) else FAILURE


class SetBlackboard(SyncAction):
    """Writes `value` (a literal, or `{src}` copied with its type) into the entry named by output_key."""

    PORTS = [
        PortSpec("value", type="any", description="Value to be written into the output_key"),
        PortSpec(
            "output_key",
            PortDirection.INOUT,
            "any",
            description="Name of the blackboard entry where the value should be written",
        ),
    ]

    def tick(self) -> int:  # type: ignore[override]
        key = str(self.require_input("output_key"))
        raw = self.ports.get("value")
        if raw is None:
            raise BTRuntimeError("missing port [value]", node_path=self.path)
        board = self.board
        dst = board.get_entry(key)
        src_key = blackboard_key(raw)
        if src_key is not None:
            src = board.get_entry(src_key)
            if src is None:
                raise BTRuntimeError("Can't find the port referred by [value]", node_path=self.path)
            if dst is None:
                dst = board.create_entry(key, src.type)
            value = src.value
        else:
            value = raw
        if value is EMPTY:
            return FAILURE
        parsed_as = None
        if dst is not None and dst.type != "string" and isinstance(value, str):
            # BT.CPP parses the string with the entry's converter; an entry without one
            # (untyped, or a script's) receives an empty value.
            if dst.type == "Any":
                raise BTRuntimeError(
                    f"Can't convert string [{value}] to type [BT::Any]: BT.CPP has no "
                    "convertFromString for BT::Any",
                    node_path=self.path,
                )
            if parses_text(dst.type):
                text = value
                try:
                    value = convert_string(text, dst.type, self.rt.enums)
                except ValueError as err:
                    raise BTRuntimeError(
                        f"Can't convert string [{text}] to type [{dst.type}]: {err}", node_path=self.path
                    ) from None
                if dst.cpp_type is not None and not literal_fits(value, dst.cpp_type, cpp_widths=True):
                    raise BTRuntimeError(
                        f"Can't convert string [{text}] to type [{dst.cpp_type}]: Value out of bound "
                        f"when converting [{text}] to integer",
                        node_path=self.path,
                    )
                # Parsed into the entry's own type (a queue, say), which set() must know.
                parsed_as = dst.type
            elif not strongly_typed(dst.type):
                value = EMPTY
            # Else an enum without a converter: set() refuses the text, as BT.CPP's does.
        try:
            board.set(key, value, "Any", parsed_as)
        except ScriptError as err:
            raise BTRuntimeError(err.message, node_path=self.path) from None
        return SUCCESS


class UnsetBlackboard(SyncAction):
    PORTS = [PortSpec("key", type="string", description="Key of the entry to remove")]

    def tick(self) -> int:  # type: ignore[override]
        self.board.unset(str(self.require_input("key")))
        return SUCCESS


class WasEntryUpdated(SyncAction):
    PORTS = [PortSpec("entry", type="BT::Any", description="Entry to check")]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.seq = 0
        self.key = entry_key(self)

    def tick(self) -> int:  # type: ignore[override]
        entry = self.board.get_entry(self.key)
        if entry is None:
            return FAILURE
        previous, self.seq = self.seq, entry.seq
        return SUCCESS if previous != entry.seq else FAILURE


class Sleep(StatefulAction):
    """RUNNING until `msec` elapsed on the wall clock (a timer wakes the tree up), then SUCCESS."""

    PORTS = [PortSpec("msec", type="unsigned", required=True)]
    SIGNALS_WAKE_UP = True

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.waiting = False
        self.timer: Timer | None = None

    def _fire(self) -> None:
        self.waiting = False
        self.rt.wake_up()

    def on_start(self) -> int:  # type: ignore[override]
        msec = int(self.require_input("msec"))
        if msec <= 0:
            return SUCCESS
        self.set_status(RUNNING)
        self.waiting = True
        self.timer = self.rt.add_timer(msec / 1000.0, self._fire)
        return RUNNING

    def on_running(self) -> int:  # type: ignore[override]
        return RUNNING if self.waiting else SUCCESS

    def on_halted(self) -> None:
        self.waiting = False
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
