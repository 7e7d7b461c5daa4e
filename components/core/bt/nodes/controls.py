"""Built-in sequence and fallback controls (plain, async, with memory, reactive) with BT.CPP 4 semantics."""

from __future__ import annotations

from coral_core.bt.errors import BTRuntimeError
from coral_core.bt.nodes.base import ControlNode, NodeConfig
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SKIPPED, SUCCESS


class Sequence(ControlNode):
    """Ticks children in order, resuming at a RUNNING child; FAILURE resets; all SUCCESS -> SUCCESS."""

    ASYNC = False
    ON_DONE = SUCCESS  # the child result that moves on
    ON_STOP = FAILURE  # the child result that ends the sequence
    MEMORY = False  # a stop keeps the index (halting the children from it) instead of starting over

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.index = 0
        self.skipped = 0

    def tick(self) -> int:
        children = self.children
        count = len(children)
        if self._status == IDLE or self._status == SKIPPED:
            self.skipped = 0
        self.set_status(RUNNING)
        done, stop = self.ON_DONE, self.ON_STOP
        while self.index < count:
            child = children[self.index]
            prev = child._status
            st = child.execute_tick()
            if st == RUNNING:
                return RUNNING
            if st == stop:
                if self.MEMORY:
                    self.halt_children_from(self.index)
                else:
                    self.reset_children()
                    self.index = 0
                return st
            if st == done:
                self.index += 1
                if self.ASYNC and prev == IDLE and self.index < count:
                    self.rt.wake_up()
                    return RUNNING
            elif st == SKIPPED:
                self.index += 1
                self.skipped += 1
            else:
                raise BTRuntimeError("a child returned IDLE", node_path=self.path)
        all_skipped = self.skipped == count
        if self.index == count:
            self.reset_children()
            self.index = 0
            self.skipped = 0
        return SKIPPED if all_skipped else done

    def halt(self) -> None:
        self.index = 0
        self.skipped = 0
        ControlNode.halt(self)


class AsyncSequence(Sequence):
    ASYNC = True


class Fallback(Sequence):
    ON_DONE = FAILURE
    ON_STOP = SUCCESS


class AsyncFallback(Fallback):
    ASYNC = True


class SequenceWithMemory(Sequence):
    """Like Sequence, but FAILURE keeps the index: the next tick resumes at the failed child."""

    ASYNC = True
    MEMORY = True

    def halt(self) -> None:
        # BT.CPP's SequenceWithMemory keeps its index through a halt too.
        ControlNode.halt(self)


class ReactiveSequence(ControlNode):
    """Restarts at child 0 every tick; a RUNNING child halts all the others."""

    SIGNALS_WAKE_UP = False  # its conditions are re-checked on every tick

    ON_STOP = FAILURE
    ON_END = SUCCESS

    def tick(self) -> int:
        all_skipped = True
        self.set_status(RUNNING)
        children = self.children
        stop = self.ON_STOP
        for index, child in enumerate(children):
            st = child.execute_tick()
            all_skipped = all_skipped and st == SKIPPED
            if st == RUNNING:
                for i in range(len(children)):
                    if i != index:
                        self.halt_child(i)
                return RUNNING
            if st == stop:
                self.reset_children()
                return stop
            if st == SKIPPED:
                self.halt_child(index)
            elif st == IDLE:
                raise BTRuntimeError("a child returned IDLE", node_path=self.path)
        self.reset_children()
        return SKIPPED if all_skipped else self.ON_END


class ReactiveFallback(ReactiveSequence):
    ON_STOP = SUCCESS
    ON_END = FAILURE
