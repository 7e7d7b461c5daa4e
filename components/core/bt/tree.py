"""An instantiated tree: BT.CPP's three tick modes with wake-ups, halting, the transition stream,
snapshots, unicode rendering and per-tick timing. Built by `TreeDocument.build`; driven by executors.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from coral_core.bt.blackboard import Blackboard
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SUCCESS, Status

if TYPE_CHECKING:
    from coral_core.bt.nodes.base import TreeNode
    from coral_core.bt.runtime import Runtime

_EXACTLY_ONCE, _ONCE, _WHILE_RUNNING = 0, 1, 2


@dataclass(frozen=True)
class Transition:
    timestamp: float
    uid: int
    path: str
    node_id: str
    previous: Status
    status: Status


@dataclass(frozen=True)
class NodeState:
    uid: int
    path: str
    node_id: str
    name: str
    status: Status
    last_result: Status  # SUCCESS/FAILURE of the last completion, IDLE if it never completed


@dataclass(frozen=True)
class TreeSnapshot:
    root_status: Status
    tick_count: int
    nodes: list[NodeState]


_SYMBOL = {IDLE: "-", RUNNING: "*", SUCCESS: "✔", FAILURE: "✕", Status.SKIPPED: "⤼"}


class Tree:
    def __init__(
        self,
        root: TreeNode,
        runtime: Runtime,
        root_blackboard: Blackboard,
        nodes: list[TreeNode],
        warnings: list[str] | None = None,
    ) -> None:
        self.root = root
        self.runtime = runtime
        self.root_blackboard = root_blackboard
        self.nodes = nodes
        self.warnings = list(warnings or [])
        self.tick_count = 0
        self.last_tick_duration_s = 0.0
        self.last_status: Status = Status.IDLE
        # The ID of the <BehaviorTree> the root belongs to (set by the builder).
        self.main_tree_id = "MainTree"
        self._listeners: list[Callable[[Transition], None]] = []
        self._status_observers: list[Callable[[TreeNode, int, int], None]] = []

    # ticking ----------------------------------------------------------------------------
    def _execute(self) -> int:
        with self.runtime.lock:
            start = time.perf_counter()
            try:
                status = self.root.execute_tick()
            finally:
                self.last_tick_duration_s = time.perf_counter() - start
                self.tick_count += 1
        return status

    def _tick_root(self, mode: int, sleep_s: float = 0.0) -> Status:
        status = IDLE
        rt = self.runtime
        while status == IDLE or (mode == _WHILE_RUNNING and status == RUNNING):
            status = self._execute()
            while mode != _EXACTLY_ONCE and status == RUNNING and rt.consume_wake_up(0.0):
                status = self._execute()
            if status == SUCCESS or status == FAILURE:
                with rt.lock:
                    self.root.reset_status()
            if status == RUNNING and mode == _WHILE_RUNNING:
                rt.consume_wake_up(sleep_s)
        self.last_status = Status(status)
        return self.last_status

    def tick_exactly_once(self) -> Status:
        return self._tick_root(_EXACTLY_ONCE)

    def tick_once(self) -> Status:
        return self._tick_root(_ONCE)

    def tick_while_running(self, sleep_s: float = 0.01) -> Status:
        return self._tick_root(_WHILE_RUNNING, sleep_s)

    def halt(self) -> None:
        """BT.CPP's `haltTree()`: halt the root, then every node in document order (so each
        `_onHalted` runs, for idle nodes too, and a running node its parent no longer ticks is
        halted), then reset the root."""
        with self.runtime.lock:
            self.root.halt_node()
            for node in self.nodes:
                node.halt_node()
            self.root.reset_status()

    def wake_up(self) -> None:
        self.runtime.wake_up()

    def wait_for_wake_up(self, timeout_s: float) -> bool:
        return self.runtime.consume_wake_up(timeout_s)

    def needs_polling(self) -> bool:
        """True while some RUNNING node could change on a tick without a wake-up (see
        `TreeNode.SIGNALS_WAKE_UP`); False lets an executor sleep until the next wake-up."""
        return any(node.polled_while_running for node in self.nodes)

    # observability ------------------------------------------------------------------------
    def add_transition_listener(self, fn: Callable[[Transition], None]) -> None:
        self._listeners.append(fn)
        self._route_observers()

    def remove_transition_listener(self, fn: Callable[[Transition], None]) -> None:
        self._listeners.remove(fn)
        self._route_observers()

    def add_status_observer(self, fn: Callable[[TreeNode, int, int], None]) -> None:
        """A raw observer `fn(node, previous, status)` on the tick thread, with no `Transition`
        built for it: for recorders that must cost the tick next to nothing (the Groot2 publisher)."""
        self._status_observers.append(fn)
        self._route_observers()

    def remove_status_observer(self, fn: Callable[[TreeNode, int, int], None]) -> None:
        self._status_observers.remove(fn)
        self._route_observers()

    def _route_observers(self) -> None:
        raw = list(self._status_observers)
        if self._listeners:
            raw.append(self._on_transition)
        if not raw:
            self.runtime.observer = None
        elif len(raw) == 1:
            self.runtime.observer = raw[0]
        else:

            def fan_out(node: TreeNode, previous: int, status: int) -> None:
                for fn in raw:
                    fn(node, previous, status)

            self.runtime.observer = fan_out

    def _on_transition(self, node: TreeNode, previous: int, status: int) -> None:
        event = Transition(
            self.runtime.clock(), node.uid, node.path, node.node_id, Status(previous), Status(status)
        )
        for fn in list(self._listeners):
            fn(event)

    def snapshot(self) -> TreeSnapshot:
        with self.runtime.lock:
            nodes = [
                NodeState(n.uid, n.path, n.node_id, n.name, Status(n._status), Status(n.last_result))
                for n in self.nodes
            ]
            return TreeSnapshot(Status(self.root._status), self.tick_count, nodes)

    def node_by_path(self, path: str) -> TreeNode | None:
        for node in self.nodes:
            if node.path == path:
                return node
        return None

    def render_unicode(self) -> str:
        lines: list[str] = []

        def label(node: TreeNode) -> str:
            st = node._status
            text = f"{_SYMBOL.get(st, '?')} {node.name}"
            if node.name != node.node_id:
                text += f" ({node.node_id})"
            text += f" [{Status(st).name}"
            if st == IDLE and node.last_result in (SUCCESS, FAILURE):
                text += f" after {Status(node.last_result).name}"
            return text + "]"

        def walk(node: TreeNode, prefix: str, last: bool, top: bool) -> None:
            if top:
                lines.append(label(node))
                child_prefix = ""
            else:
                lines.append(prefix + ("└── " if last else "├── ") + label(node))
                child_prefix = prefix + ("    " if last else "│   ")
            for i, child in enumerate(node.children):
                walk(child, child_prefix, i == len(node.children) - 1, False)

        walk(self.root, "", True, True)
        return "\n".join(lines)
