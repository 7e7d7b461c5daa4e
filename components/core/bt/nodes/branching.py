"""Built-in branching controls (IfThenElse, WhileDoElse, Switch2..6, TryCatch) with BT.CPP 4 semantics."""

from __future__ import annotations

from coral_core.bt.errors import BTRuntimeError
from coral_core.bt.nodes.base import ControlNode, NodeConfig
from coral_core.bt.ports import PortSpec
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SKIPPED, SUCCESS

EPSILON = 1.1920928955078125e-07  # Switch compares reals within float epsilon, as BT.CPP does


class IfThenElse(ControlNode):
    """Condition ticked once, branch latched while RUNNING (not reactive)."""

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.branch = 0

    def tick(self) -> int:
        children = self.children
        count = len(children)
        if count not in (2, 3):
            raise BTRuntimeError("IfThenElseNode must have either 2 or 3 children", node_path=self.path)
        self.set_status(RUNNING)
        if self.branch == 0:
            cond = children[0].execute_tick()
            if cond == RUNNING:
                return RUNNING
            if cond == SUCCESS:
                self.branch = 1
            elif cond == FAILURE:
                if count == 3:
                    self.branch = 2
                else:
                    return FAILURE
        if self.branch > 0:
            st = children[self.branch].execute_tick()
            if st == RUNNING:
                return RUNNING
            self.reset_children()
            self.branch = 0
            return st
        raise BTRuntimeError("the condition of IfThenElse returned SKIPPED", node_path=self.path)

    def halt(self) -> None:
        self.branch = 0
        ControlNode.halt(self)


class WhileDoElse(ControlNode):
    """Reactive: the condition is re-ticked every tick; a change of branch halts the other one."""

    SIGNALS_WAKE_UP = False

    def tick(self) -> int:
        children = self.children
        count = len(children)
        if count not in (2, 3):
            raise BTRuntimeError("WhileDoElseNode must have either 2 or 3 children", node_path=self.path)
        self.set_status(RUNNING)
        cond = children[0].execute_tick()
        if cond == RUNNING:
            return RUNNING
        st = IDLE
        if cond == SUCCESS:
            if count == 3:
                self.halt_child(2)
            st = children[1].execute_tick()
        elif cond == FAILURE:
            if count == 3:
                self.halt_child(1)
                st = children[2].execute_tick()
            else:
                st = FAILURE
        if st == RUNNING:
            return RUNNING
        self.reset_children()
        return st


def switch_equal(variable: str, case: str, enums: dict[str, int] | object) -> bool:
    """String match first, then integer, then double (epsilon); enum names resolve to their value."""
    if variable == case:
        return True
    table = enums if isinstance(enums, dict) else {}

    def as_number(text: str) -> float | None:
        t = text.strip()
        if t in table:
            return float(table[t])
        try:
            return float(int(t))
        except ValueError:
            pass
        try:
            return float(t)
        except ValueError:
            return None

    a, b = as_number(variable), as_number(case)
    return a is not None and b is not None and abs(a - b) <= EPSILON


class SwitchBase(ControlNode):
    CASES = 2
    SIGNALS_WAKE_UP = False  # the variable is read again on every tick

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.running_child = -1

    def tick(self) -> int:
        children = self.children
        if len(children) != self.CASES + 1:
            raise BTRuntimeError(
                "Wrong number of children in SwitchNode; must be (num_cases + default)", node_path=self.path
            )
        match = self.CASES
        variable = self.get_input("variable")
        if variable is not None:
            variable = _as_text(variable)
            for i in range(self.CASES):
                case = self.get_input(f"case_{i + 1}")
                if case is not None and switch_equal(variable, _as_text(case), dict(self.rt.enums)):
                    match = i
                    break
        if self.running_child != -1 and self.running_child != match:
            self.halt_child(self.running_child)
        st = children[match].execute_tick()
        if st == SKIPPED:
            self.running_child = -1
            return SKIPPED
        if st == RUNNING:
            self.running_child = match
        else:
            self.reset_children()
            self.running_child = -1
        return st

    def halt(self) -> None:
        self.running_child = -1
        ControlNode.halt(self)


def _as_text(value: object) -> str:
    if isinstance(value, float) and value == int(value):
        return str(int(value))
    return str(value)


def _switch(n: int) -> type[SwitchBase]:
    ports = [PortSpec("variable", type="string")] + [
        PortSpec(f"case_{i}", type="string") for i in range(1, n + 1)
    ]
    return type(f"Switch{n}", (SwitchBase,), {"CASES": n, "PORTS": ports})


SWITCHES = {f"Switch{n}": _switch(n) for n in range(2, 7)}


class TryCatch(ControlNode):
    """Children 0..N-2 run as a Sequence (try); on try FAILURE the last child (catch) runs and the
    node returns FAILURE whatever the catch returns. With catch_on_halt, a halt during the try also
    runs the catch (synchronously, once)."""

    PORTS = [PortSpec("catch_on_halt", type="bool", default="false")]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.index = 0
        self.skipped = 0
        self.in_catch = False

    def tick(self) -> int:
        children = self.children
        if len(children) < 2:
            raise BTRuntimeError("TryCatch needs at least 2 children", node_path=self.path)
        if self._status == IDLE or self._status == SKIPPED:
            self.skipped = 0
            self.in_catch = False
        self.set_status(RUNNING)
        last = len(children) - 1
        if not self.in_catch:
            while self.index < last:
                st = children[self.index].execute_tick()
                if st == RUNNING:
                    return RUNNING
                if st == FAILURE:
                    self.reset_children()
                    self.index = 0
                    self.in_catch = True
                    break
                if st == SKIPPED:
                    self.skipped += 1
                self.index += 1
            else:
                all_skipped = self.skipped == last
                self.reset_children()
                self.index = 0
                self.skipped = 0
                return SKIPPED if all_skipped else SUCCESS
        st = children[last].execute_tick()
        if st == RUNNING:
            return RUNNING
        self.reset_children()
        self.in_catch = False
        return FAILURE

    def halt(self) -> None:
        active = self._status in (RUNNING, SUCCESS, FAILURE)
        if active and not self.in_catch and self.get_input("catch_on_halt", False):
            last = len(self.children) - 1
            for i in range(last):
                self.halt_child(i)
            if self.children[last].execute_tick() == RUNNING:
                self.halt_child(last)
        self.index = 0
        self.skipped = 0
        self.in_catch = False
        ControlNode.halt(self)
