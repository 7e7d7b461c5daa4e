"""Built-in Parallel and ParallelAll controls with BT.CPP 4 semantics; registered by the registry."""

from __future__ import annotations

from coral_core.bt.errors import BTRuntimeError
from coral_core.bt.nodes.base import ControlNode, NodeConfig
from coral_core.bt.ports import PortSpec
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SKIPPED, SUCCESS


def _threshold(value: int, count: int) -> int:
    return max(count + value + 1, 0) if value < 0 else value


def _reachable(node: ControlNode, count: int, needed: int, outcome: str) -> None:
    """Refuses, as BT.CPP does, a threshold of more children than the node has."""
    if count < needed:
        raise BTRuntimeError(
            f"Number of children is less than threshold. Can never {outcome}.", node_path=node.path
        )


class Parallel(ControlNode):
    """M-of-N success / F-of-N failure with early exit; completed children are not re-ticked."""

    PORTS = [
        PortSpec("success_count", type="int", default="-1"),
        PortSpec("failure_count", type="int", default="1"),
    ]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.completed: set[int] = set()
        self.successes = 0
        self.failures = 0

    def tick(self) -> int:
        s_raw = int(self.require_input("success_count"))
        f_raw = int(self.require_input("failure_count"))
        children = self.children
        count = len(children)
        need_s = _threshold(s_raw, count)
        need_f = _threshold(f_raw, count)
        _reachable(self, count, need_s, "succeed")
        _reachable(self, count, need_f, "fail")
        self.set_status(RUNNING)
        skipped = 0
        for i, child in enumerate(children):
            if i not in self.completed:
                st = child.execute_tick()
                if st == SKIPPED:
                    skipped += 1
                elif st == SUCCESS:
                    self.completed.add(i)
                    self.successes += 1
                elif st == FAILURE:
                    self.completed.add(i)
                    self.failures += 1
                elif st == IDLE:
                    raise BTRuntimeError("a child returned IDLE", node_path=self.path)
            if self.successes >= need_s or (s_raw < 0 and self.successes + skipped >= need_s):
                self._clear()
                self.reset_children()
                return SUCCESS
            if count - self.failures < need_s or self.failures == need_f:
                self._clear()
                self.reset_children()
                return FAILURE
        return SKIPPED if skipped == count else RUNNING

    def _clear(self) -> None:
        self.completed.clear()
        self.successes = 0
        self.failures = 0

    def halt(self) -> None:
        self._clear()
        ControlNode.halt(self)


class ParallelAll(ControlNode):
    """Runs every child to completion; FAILURE if failures >= max_failures."""

    PORTS = [PortSpec("max_failures", type="int", default="1")]

    def __init__(self, name: str, config: NodeConfig) -> None:
        super().__init__(name, config)
        self.completed: set[int] = set()
        self.failures = 0

    def tick(self) -> int:
        children = self.children
        count = len(children)
        need_f = _threshold(int(self.require_input("max_failures")), count)
        _reachable(self, count, need_f, "fail")
        self.set_status(RUNNING)
        skipped = 0
        for i, child in enumerate(children):
            if i in self.completed:
                continue
            st = child.execute_tick()
            if st == SUCCESS:
                self.completed.add(i)
            elif st == FAILURE:
                self.completed.add(i)
                self.failures += 1
            elif st == SKIPPED:
                skipped += 1
            elif st == IDLE:
                raise BTRuntimeError("a child returned IDLE", node_path=self.path)
        if skipped == count:
            return SKIPPED
        if skipped + len(self.completed) >= count:
            self.halt_children_from(0)
            self.completed.clear()
            result = FAILURE if self.failures >= need_f else SUCCESS
            self.failures = 0
            return result
        return RUNNING

    def halt(self) -> None:
        self.completed.clear()
        self.failures = 0
        ControlNode.halt(self)
