"""Wall-clock decorators Timeout and Delay (timer threads that wake the tree up); BT.CPP semantics."""

from __future__ import annotations

from coral_core.bt.nodes.base import DecoratorNode, NodeConfig
from coral_core.bt.ports import PortSpec
from coral_core.bt.runtime import Timer
from coral_core.bt.status import FAILURE, RUNNING, SUCCESS


class Timeout(DecoratorNode):
    """Halts the RUNNING child from a timer thread when `msec` expires; the next tick returns FAILURE."""

    PORTS = [
        PortSpec(
            "msec",
            type="unsigned",
            required=True,
            description="After a certain amount of time, halt() the child if it is still running.",
        )
    ]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.started = False
        self.child_halted = False
        self.timer: Timer | None = None

    def _expire(self) -> None:
        child = self.children[0]
        if child._status == RUNNING:
            self.child_halted = True
            self.reset_child()
            self.rt.wake_up()

    def tick(self) -> int:
        msec = int(self.require_input("msec"))
        if not self.started:
            self.started = True
            self.set_status(RUNNING)
            self.child_halted = False
            if msec > 0:
                self.timer = self.rt.add_timer(msec / 1000.0, self._expire)
        if self.child_halted:
            self.started = False
            return FAILURE
        st = self.children[0].execute_tick()
        if st == SUCCESS or st == FAILURE:
            self.started = False
            self._cancel()
            self.reset_child()
        return st

    def _cancel(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None

    def halt(self) -> None:
        self.started = False
        self._cancel()
        DecoratorNode.halt(self)


class Delay(DecoratorNode):
    """RUNNING without ticking the child until `delay_msec` elapsed (wall clock), then mirrors it."""

    PORTS = [
        PortSpec(
            "delay_msec",
            type="unsigned",
            required=True,
            description="Tick the child after a few milliseconds",
        )
    ]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.started = False
        self.complete = False
        self.timer: Timer | None = None

    def _fire(self) -> None:
        self.complete = True
        self.rt.wake_up()

    def tick(self) -> int:
        msec = int(self.require_input("delay_msec"))
        if not self.started:
            self.complete = False
            self.started = True
            self.set_status(RUNNING)
            if msec > 0:
                self.timer = self.rt.add_timer(msec / 1000.0, self._fire)
            else:
                # BT.CPP's timer thread fires a zero delay at once, so the next tick (or tick_once's
                # own re-tick) runs the child; a Python timer thread waits for the GIL instead.
                self._fire()
                return RUNNING
        if not self.complete:
            return RUNNING
        st = self.children[0].execute_tick()
        if st == SUCCESS or st == FAILURE:
            self.started = False
            self.reset_child()
        return st

    def halt(self) -> None:
        self.started = False
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        DecoratorNode.halt(self)
