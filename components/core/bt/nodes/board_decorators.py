"""Blackboard-driven decorators: Loop* (queues), SkipUnlessUpdated/WaitValueUpdate and the v3
BlackboardCheck* nodes, with BT.CPP semantics; registered by the registry."""

from __future__ import annotations

from collections import deque
from typing import Any

from coral_core.bt.anyvalue import EMPTY, kind_of, std_to_string
from coral_core.bt.errors import BTRuntimeError
from coral_core.bt.nodes.base import DecoratorNode, NodeConfig
from coral_core.bt.ports import PortSpec, blackboard_key, convert_string, normalize_type
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SKIPPED, SUCCESS, PortDirection


class LoopBase(DecoratorNode):
    """Pops one queue element per child run into `value`; RUNNING after each completed child."""

    SIGNALS_WAKE_UP = False  # RUNNING between two runs of its child, waiting for the next tick

    ELEMENT = "any"

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.child_running = False
        self.static_queue: list[Any] | None = None
        self.current: deque[Any] | None = None
        raw = config.ports.get("queue")
        if raw is not None and blackboard_key(raw) is None:
            self.static_queue = list(convert_string(raw, "queue:" + self.ELEMENT, self.rt.enums))

    def tick(self) -> int:
        popped = False
        if self._status == IDLE:
            self.child_running = False
            if self.static_queue is not None:
                self.current = deque(self.static_queue)
        if not self.child_running:
            if self.static_queue is None:
                self.current = self._board_queue()
            if self.current:
                value = self.current.popleft()
                popped = True
                self.set_output("value", value)
        if not popped and not self.child_running:
            return int(self.require_input("if_empty"))
        if self._status == IDLE:
            self.set_status(RUNNING)
        st = self.children[0].execute_tick()
        self.child_running = st == RUNNING
        if st == SUCCESS or st == FAILURE:
            self.reset_child()
        return FAILURE if st == FAILURE else RUNNING

    def _board_queue(self) -> deque[Any] | None:
        key = blackboard_key(self.ports.get("queue", "") or "")
        if not key:
            return None
        entry = self.board.get_entry(key)
        if entry is None:
            return self.current
        value = entry.value
        if value is EMPTY:
            raise BTRuntimeError("Any::cast failed because it is empty: [queue]", node_path=self.path)
        if isinstance(value, deque):
            return value  # a shared queue is consumed in place
        if isinstance(value, str):
            # BT.CPP 4.10 also reads a queue written as text ("1;2;3").
            try:
                converted = deque(convert_string(value, "queue:" + self.ELEMENT, self.rt.enums))
            except ValueError as err:
                raise BTRuntimeError(f"[queue]: {err}", node_path=self.path) from None
            entry.value = converted
            return converted
        if isinstance(value, list):
            # A vector entry is copied when the loop starts (4.10).
            if self.current is None or self._status == IDLE:
                return deque(value)
            return self.current
        raise BTRuntimeError(
            f"[queue]: no known safe conversion between [{kind_of(value)}] and [std::deque<{self.ELEMENT}>] "
            f"(the entry holds {std_to_string(value)}, not a queue)",
            node_path=self.path,
        )


def _loop(node_id: str, elem: str) -> type[LoopBase]:
    ports = [
        PortSpec("queue", PortDirection.INOUT, f"std::deque<{elem}>"),
        PortSpec("if_empty", type="NodeStatus", default="SUCCESS"),
        PortSpec("value", PortDirection.OUTPUT, elem),
    ]
    return type(node_id, (LoopBase,), {"ELEMENT": normalize_type(elem), "PORTS": ports})


LOOPS = {
    "LoopInt": _loop("LoopInt", "int"),
    "LoopBool": _loop("LoopBool", "bool"),
    "LoopDouble": _loop("LoopDouble", "double"),
    "LoopString": _loop("LoopString", "std::string"),
}


def entry_key(node: DecoratorNode | Any) -> str:
    raw = node.ports.get("entry")
    if not raw:
        raise BTRuntimeError("missing port 'entry'", node_path=node.path)
    key = blackboard_key(raw)
    return key if key is not None else raw


class EntryUpdatedDecorator(DecoratorNode):
    PORTS = [PortSpec("entry", type="BT::Any", description="Entry to check")]
    SIGNALS_WAKE_UP = False  # WaitValueUpdate is RUNNING until the entry changes
    IF_NOT_UPDATED: int = SKIPPED

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.seq = 0
        self.executing = False
        self.key = entry_key(self)

    def tick(self) -> int:
        child = self.children[0]
        if self.executing:
            st = child.execute_tick()
            self.executing = st == RUNNING
            return st
        entry = self.board.get_entry(self.key)
        if entry is None:
            return self.IF_NOT_UPDATED
        previous, self.seq = self.seq, entry.seq
        if previous == entry.seq:
            return self.IF_NOT_UPDATED
        st = child.execute_tick()
        self.executing = st == RUNNING
        return st

    def halt(self) -> None:
        # BT.CPP's EntryUpdatedDecorator::halt only forgets the running child: it neither halts the
        # child nor resets itself (the parent resets it). Kept identical for conformance.
        self.executing = False


class SkipUnlessUpdated(EntryUpdatedDecorator):
    IF_NOT_UPDATED = SKIPPED


class WaitValueUpdate(EntryUpdatedDecorator):
    IF_NOT_UPDATED = RUNNING


class BlackboardCheck(DecoratorNode):
    """v3 `BlackboardCheck*`: ticks the child if value_A equals value_B, else returns return_on_mismatch."""

    TYPE = "string"
    PORTS = [
        PortSpec("value_A"),
        PortSpec("value_B"),
        PortSpec("return_on_mismatch", type="NodeStatus", default="FAILURE"),
    ]

    def tick(self) -> int:
        a = self.get_input("value_A")
        b = self.get_input("value_B")
        mismatch = int(self.require_input("return_on_mismatch"))
        child = self.children[0]
        if child._status == RUNNING or _v3_equal(a, b, self.TYPE):
            self.set_status(RUNNING)
            return child.execute_tick()
        return mismatch


def _v3_equal(a: object, b: object, type_name: str) -> bool:
    if a is None or b is None:
        return False
    try:
        return bool(convert_string(str(a), type_name) == convert_string(str(b), type_name))
    except ValueError:
        return False


BLACKBOARD_CHECKS = {
    f"BlackboardCheck{suffix}": type(f"BlackboardCheck{suffix}", (BlackboardCheck,), {"TYPE": typ})
    for suffix, typ in (("Int", "int"), ("Double", "double"), ("String", "string"), ("Bool", "bool"))
}
