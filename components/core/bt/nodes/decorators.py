"""Built-in decorators with BT.CPP 4 semantics (BT_SEMANTICS 1.4); registered by the registry."""

from __future__ import annotations

from typing import Any

from coral_core.bt.errors import BTRuntimeError, ScriptError
from coral_core.bt.nodes.base import DecoratorNode, NodeConfig
from coral_core.bt.ports import PortSpec, blackboard_key
from coral_core.bt.scripting import compile_script
from coral_core.bt.scripting.values import truthy
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SKIPPED, SUCCESS


class Inverter(DecoratorNode):
    def tick(self) -> int:
        self.set_status(RUNNING)
        st = self.children[0].execute_tick()
        if st == SUCCESS:
            self.reset_child()
            return FAILURE
        if st == FAILURE:
            self.reset_child()
            return SUCCESS
        return st


class ForceSuccess(DecoratorNode):
    RESULT = SUCCESS

    def tick(self) -> int:
        self.set_status(RUNNING)
        st = self.children[0].execute_tick()
        if st == SUCCESS or st == FAILURE:
            self.reset_child()
            return self.RESULT
        return st


class ForceFailure(ForceSuccess):
    RESULT = FAILURE


class KeepRunningUntilFailure(DecoratorNode):
    SIGNALS_WAKE_UP = False  # RUNNING after a child success, to run it again on the next tick

    def tick(self) -> int:
        self.set_status(RUNNING)
        st = self.children[0].execute_tick()
        if st == FAILURE:
            self.reset_child()
            return FAILURE
        if st == SUCCESS:
            self.reset_child()
            return RUNNING
        if st == RUNNING:
            return RUNNING
        return self._status


class _Loop(DecoratorNode):
    """Ticks the child again while it returns `AGAIN`, up to the port's count (-1 = forever), and
    yields after a synchronous `AGAIN`; the other final result ends the loop at once.

    `Repeat` and `RetryUntilSuccessful` are this loop with SUCCESS and FAILURE swapped, as in BT.CPP
    (repeat_node.cpp, retry_node.cpp).
    """

    AGAIN: int
    COUNT_PORT: str
    REREAD_COUNT = False
    """Read the count again after every `AGAIN`, as BT.CPP's retry does (its repeat reads it once)."""

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.count = 0

    def tick(self) -> int:
        limit = int(self.require_input(self.COUNT_PORT))
        loop = self.count < limit or limit == -1
        self.set_status(RUNNING)
        child = self.children[0]
        again = self.AGAIN
        while loop:
            prev = child._status
            st = child.execute_tick()
            if st == again:
                self.count += 1
                if self.REREAD_COUNT:
                    limit = int(self.get_input(self.COUNT_PORT, limit))
                loop = self.count < limit or limit == -1
                self.reset_child()
                if prev == IDLE and loop:
                    self.rt.wake_up()
                    return RUNNING
            elif st == SUCCESS or st == FAILURE:
                self.count = 0
                self.reset_child()
                return st
            elif st == RUNNING:
                return RUNNING
            elif st == SKIPPED:
                self.reset_child()
                return SKIPPED
            else:
                raise BTRuntimeError("a child returned IDLE", node_path=self.path)
        self.count = 0
        return again

    def halt(self) -> None:
        self.count = 0
        DecoratorNode.halt(self)


class Repeat(_Loop):
    """Repeats while the child succeeds, num_cycles times (-1 = forever); yields after sync successes."""

    AGAIN = SUCCESS
    COUNT_PORT = "num_cycles"
    PORTS = [
        PortSpec(
            "num_cycles",
            type="int",
            required=True,
            description="Repeat a successful child up to N times. Use -1 to create an infinite loop.",
        )
    ]


class RetryUntilSuccessful(_Loop):
    """Retries while the child fails, num_attempts times (-1 = forever); re-reads the port each failure."""

    AGAIN = FAILURE
    COUNT_PORT = "num_attempts"
    REREAD_COUNT = True
    PORTS = [
        PortSpec(
            "num_attempts",
            type="int",
            required=True,
            description="Execute again a failing child up to N times. Use -1 to create an infinite loop.",
        )
    ]


class RunOnce(DecoratorNode):
    PORTS = [PortSpec("then_skip", type="bool", default="true")]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.done = False
        self.result: int = IDLE

    def tick(self) -> int:
        try:
            skip = bool(self.get_input("then_skip", True))
        except BTRuntimeError:
            # BT.CPP ignores an entry that does not convert and keeps the default.
            skip = True
        if self.done:
            return SKIPPED if skip else self.result
        self.set_status(RUNNING)
        st = self.children[0].execute_tick()
        if st == SUCCESS or st == FAILURE:
            self.done = True
            self.result = st
            self.reset_child()
        return st


class Precondition(DecoratorNode):
    """Ticks the child only if `if` is true (checked again only after the child completes)."""

    PORTS = [
        PortSpec("if", type="string", required=True),
        PortSpec("else", type="NodeStatus", default="FAILURE"),
    ]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.child_running = False
        self._script_text: str | None = None
        self._script: Any = None
        raw = config.ports.get("if")
        if raw is not None and blackboard_key(raw) is None:
            self._load(raw)

    def _load(self, text: str) -> None:
        if text != self._script_text:
            self._script = compile_script(text)
            self._script_text = text

    def tick(self) -> int:
        text = self.require_input("if")
        try:
            self._load(str(text))
        except ScriptError as err:
            raise BTRuntimeError(err.message, node_path=self.path) from None
        otherwise = self.require_input("else")
        if not self.child_running:
            try:
                self.child_running = truthy(self._script(self._env))
            except ScriptError as err:
                raise BTRuntimeError(
                    f"Error in script [{text}]: {err.message}", node_path=self.path
                ) from None
        if not self.child_running:
            return int(otherwise)
        st = self.children[0].execute_tick()
        if st == SUCCESS or st == FAILURE:
            self.reset_child()
            self.child_running = False
        return st

    # No halt() override on purpose: BT.CPP's Precondition keeps "child running" across a halt, so the
    # next start ticks the child without re-evaluating `if`.


class SubTreeNode(DecoratorNode):
    """The instance of a `<SubTree>`: mirrors its child (the subtree's root)."""

    PORTS = [PortSpec("_autoremap", type="bool", default="false")]

    def tick(self) -> int:
        if self._status == IDLE:
            self.set_status(RUNNING)
        st = self.children[0].execute_tick()
        if st == SUCCESS or st == FAILURE:
            self.reset_child()
        return st
