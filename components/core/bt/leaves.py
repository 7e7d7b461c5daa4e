"""Base classes for plugin nodes (actions, conditions; ControlNode/DecoratorNode for plugin composites),
following the py_trees lifecycle.

Plugins subclass these and register them in a `NodeRegistry`; inside a node use
`get_input`/`set_output`/`wake_up`/`context`. Exceptions raised in callbacks become
`BTRuntimeError`s naming the node path.
"""

from __future__ import annotations

from coral_core.bt.nodes.base import ControlNode, DecoratorNode, LeafNode, TreeNode
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SUCCESS, NodeKind, Status

__all__ = ["ConditionNode", "ControlNode", "DecoratorNode", "StatefulAction", "SyncAction", "TreeNode"]


class SyncAction(LeafNode):
    """A synchronous action: `tick()` returns SUCCESS or FAILURE, never RUNNING."""

    KIND = NodeKind.ACTION
    SYNC_ONLY = True

    def tick(self) -> Status:  # type: ignore[override]
        raise NotImplementedError


class ConditionNode(LeafNode):
    """A condition: `tick()` returns SUCCESS or FAILURE and must not change the world."""

    KIND = NodeKind.CONDITION
    SYNC_ONLY = True

    def tick(self) -> Status:  # type: ignore[override]
        raise NotImplementedError


class StatefulAction(LeafNode):
    """An asynchronous action: `on_start()` once, `on_running()` each later tick, `on_halted()` on halt.

    SUCCESS/FAILURE end the action; RUNNING means "poll me again" (call `self.wake_up()` when
    something changed so the executor re-ticks without waiting for its period).
    """

    KIND = NodeKind.ACTION

    def on_start(self) -> Status:
        raise NotImplementedError

    def on_running(self) -> Status:
        raise NotImplementedError

    def on_halted(self) -> None:
        return None

    def tick(self) -> int:  # type: ignore[override]
        prev = self._status
        if prev == IDLE:
            st = self.on_start()
        elif prev == RUNNING:
            st = self.on_running()
        else:
            return prev
        if st not in (RUNNING, SUCCESS, FAILURE):
            raise ValueError(f"{type(self).__name__} returned {st!r}; expected RUNNING, SUCCESS or FAILURE")
        return st

    def halt(self) -> None:
        if self._status == RUNNING:
            self.on_halted()
        self.reset_status()


def is_plugin_base(cls: type) -> bool:
    return cls in (SyncAction, ConditionNode, StatefulAction, TreeNode)
