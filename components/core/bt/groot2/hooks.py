"""Groot2's hooks on nodes: breakpoints and replaced results, before or after a node's tick, as
BT.CPP 4.10's `Groot2Publisher` keeps them (`insertHook`, `runHook`, `unlockBreakpoint`,
`removeHook`, `enableAllHooks`).

The server thread edits the table; the tick thread runs a hook when it ticks a hooked node
(`TreeNode.set_tick_hooks`). A breakpoint holds the tick thread until it is unlocked, disabled,
removed, its client's heartbeat is lost, or the publisher closes. A reached hook is announced
through `notify(uid)`, which only queues the message for the server thread to publish.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from coral_core.bt.groot2.protocol import BREAKPOINT, POST, PRE, REPLACE, HookRecord
from coral_core.bt.status import FAILURE, SKIPPED, SUCCESS

if TYPE_CHECKING:
    from coral_core.bt.nodes.base import TreeNode


class Hook:
    def __init__(self, record: HookRecord) -> None:
        self.record = record
        self.ready = False


class HookTable:
    def __init__(self, nodes_by_uid: dict[int, TreeNode], notify: Callable[[int], None]) -> None:
        self.nodes_by_uid = nodes_by_uid
        self.notify = notify
        # One condition guards every hook: few hooks exist, and only the server thread and the
        # tick thread touch them.
        self.cond = threading.Condition(threading.Lock())
        self.hooks: dict[tuple[int, int], Hook] = {}
        self.closed = False

    # server thread ------------------------------------------------------------------------
    def insert(self, record: HookRecord) -> None:
        """Adds a hook, or updates the one at the same place (a breakpoint turned into a replace
        hook lets the held tick go on). A uid the tree lacks is ignored, as in BT.CPP."""
        key = (record.position, record.uid)
        with self.cond:
            hook = self.hooks.get(key)
            if hook is not None:
                was_breakpoint = hook.record.mode == BREAKPOINT
                hook.record = record
                if was_breakpoint and record.mode == REPLACE:
                    hook.ready = True
                    self.cond.notify_all()
                return
            node = self.nodes_by_uid.get(record.uid)
            if node is None or self.closed:
                return
            self.hooks[key] = Hook(record)
        self._install(node)

    def unlock(self, uid: int, position: int, status: int, remove: bool) -> bool:
        with self.cond:
            hook = self.hooks.get((position, uid)) if uid in self.nodes_by_uid else None
            if hook is None:
                return False
            hook.record.desired_status = status
            hook.record.once |= remove
            if hook.record.mode == BREAKPOINT:
                hook.ready = True
                self.cond.notify_all()
        return True

    def remove(self, uid: int, position: int) -> bool:
        with self.cond:
            hook = self.hooks.pop((position, uid), None) if uid in self.nodes_by_uid else None
            if hook is None:
                return False
            hook.record.enabled = False
            self.cond.notify_all()
        self._install(self.nodes_by_uid[uid])
        return True

    def remove_all(self) -> None:
        with self.cond:
            keys = list(self.hooks)
        for position, uid in keys:
            self.remove(uid, position)

    def enable_all(self, enabled: bool) -> None:
        with self.cond:
            for hook in self.hooks.values():
                hook.record.enabled = enabled
            self.cond.notify_all()

    def dump(self) -> list[dict]:
        with self.cond:
            records = [hook.record for key, hook in sorted(self.hooks.items())]
            return [record.as_json() for record in records]

    def close(self) -> None:
        """Removes every hook and releases a held tick; no hook is added afterwards."""
        with self.cond:
            self.closed = True
        self.remove_all()

    def _install(self, node: TreeNode) -> None:
        with self.cond:
            pre = (PRE, node.uid) in self.hooks
            post = (POST, node.uid) in self.hooks
        node.set_tick_hooks(self._run_pre if pre else None, self._run_post if post else None)

    # tick thread --------------------------------------------------------------------------
    def _run_pre(self, node: TreeNode) -> int:
        return self._run(node, PRE)

    def _run_post(self, node: TreeNode, _status: int) -> int:
        return self._run(node, POST)

    def _run(self, node: TreeNode, position: int) -> int:
        """`runHook`: SKIPPED (tick as usual) unless the hook forces SUCCESS or FAILURE."""
        key = (position, node.uid)
        with self.cond:
            hook = self.hooks.get(key)
            if hook is None or not hook.record.enabled:
                return SKIPPED
        self.notify(node.uid)
        with self.cond:
            if hook.record.mode == BREAKPOINT:
                self.cond.wait_for(lambda: hook.ready or not hook.record.enabled)
                hook.ready = False
            if not hook.record.enabled:
                return SKIPPED
            status = hook.record.desired_status
            once = hook.record.once
            if once:
                hook.record.enabled = False
                if self.hooks.get(key) is hook:
                    del self.hooks[key]
        if once:
            self._install(node)
        return status if status in (SUCCESS, FAILURE) else SKIPPED
