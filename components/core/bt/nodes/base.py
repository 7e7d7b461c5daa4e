"""Base node classes: BT.CPP's executeTick/halt lifecycle on top of py_trees behaviours.

Every node is a `py_trees.behaviour.Behaviour` (so py_trees display tooling works), but ticking goes
through the lean `execute_tick()` below instead of py_trees' generator tick: pre-conditions, `tick()`,
post-conditions, then the status change reported to the tree's observer. Built by the builder.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import py_trees
from coral_core.bt.blackboard import Blackboard
from coral_core.bt.errors import BTError, BTRuntimeError, ScriptError
from coral_core.bt.nodes.port_access import PortAccess
from coral_core.bt.ports import PortSpec
from coral_core.bt.scripting import ScriptEnv
from coral_core.bt.scripting.values import truthy
from coral_core.bt.status import FAILURE, IDLE, RUNNING, SKIPPED, SUCCESS, NodeKind, Status
from py_trees import common

if TYPE_CHECKING:
    from coral_core.bt.runtime import Runtime

_PY_TREES_STATUS = {
    IDLE: common.Status.INVALID,
    RUNNING: common.Status.RUNNING,
    SUCCESS: common.Status.SUCCESS,
    FAILURE: common.Status.FAILURE,
    SKIPPED: common.Status.INVALID,
}
Script = Callable[[ScriptEnv], Any]


class NodeConfig:
    """What the builder hands to a node constructor."""

    def __init__(
        self,
        node_id: str,
        uid: int,
        path: str,
        board: Blackboard,
        runtime: Runtime,
        ports: dict[str, str],
        specs: dict[str, PortSpec],
        file: str = "",
        line: int = 0,
        cpp_widths: bool = False,
    ) -> None:
        self.node_id = node_id
        self.uid = uid
        self.path = path
        self.board = board
        self.runtime = runtime
        self.ports = ports
        self.specs = specs
        self.file = file
        self.line = line
        # BT.CPP's own nodes: their integer ports have C++ widths (`ports.fits_integer`).
        self.cpp_widths = cpp_widths


class TreeNode(PortAccess, py_trees.behaviour.Behaviour):
    """Base of every node. Subclasses implement `tick()` (BT.CPP semantics) and maybe `halt()`."""

    KIND: NodeKind = NodeKind.ACTION
    PORTS: list[PortSpec] = []
    SYNC_ONLY = False
    # BT.CPP's emitWakeUpSignal contract: True when, while this node is RUNNING, ticking it again
    # can change nothing until the tree is woken up (or a RUNNING child changes), so an executor
    # may sleep until a wake-up instead of ticking at its rate. Leaves may be polled (False);
    # controls and decorators only mirror their children (True), except those that re-check
    # something on every tick.
    SIGNALS_WAKE_UP = False
    # Injected (pre-tick, post-tick) callbacks; an instance gets its own with `set_tick_hooks`.
    tick_hooks: tuple[Callable[..., int] | None, Callable[..., int] | None] = (None, None)

    def __init__(self, name: str, config: NodeConfig) -> None:
        # Behaviour.__init__ is not called: it starts py_trees' generator tick, which we replace.
        self.id = uuid.uuid4()
        self.name = name
        self.blackboards = []
        self.qualified_name = f"{self.__class__.__qualname__}/{name}"
        self.iterator = iter(())
        self.parent = None
        self.children: list[TreeNode] = []
        self.feedback_message = ""
        self.blackbox_level = common.BlackBoxLevel.NOT_A_BLACKBOX
        self._logger: logging.Logger | None = None
        self.node_id = config.node_id
        self.uid = config.uid
        self.path = config.path
        self.board = config.board
        self.rt = config.runtime
        self.ports = config.ports
        self.port_specs = config.specs
        self.file = config.file
        self.line = config.line
        self.cpp_widths = config.cpp_widths
        self._status: int = IDLE
        # The status the node left when it was last reset (the only way back to IDLE): Groot2
        # shows an IDLE node as 10 + it.
        self._left: int = IDLE
        self.last_result: int = IDLE
        self._pre: list[tuple[int, Script]] | None = None
        self._post: dict[str, Script] | None = None
        self._script_sources: dict[str, str] = {}
        self._env = ScriptEnv(config.board, config.runtime.enums)
        self._port_cache: dict[str, tuple[str | None, Any, str]] = {}

    # py_trees compatibility -------------------------------------------------------------
    @property
    def logger(self) -> logging.Logger:  # type: ignore[override]
        if self._logger is None:
            self._logger = logging.getLogger(f"coral_core.bt.{self.name}")
        return self._logger

    @logger.setter
    def logger(self, value: logging.Logger) -> None:
        self._logger = value

    @property
    def status(self) -> common.Status:  # type: ignore[override]
        return _PY_TREES_STATUS[self._status]

    @status.setter
    def status(self, value: common.Status) -> None:
        # py_trees code may assign its own statuses; the BT status stays authoritative.
        pass

    @property
    def polled_while_running(self) -> bool:
        """RUNNING, and a tick could change it without a wake-up: it does not keep the contract
        above, or a `_while` precondition is checked on every tick."""
        if self._status != RUNNING:
            return False
        return not self.SIGNALS_WAKE_UP or any(index == 3 for index, _ in self._pre or ())

    @property
    def bt_status(self) -> Status:
        return Status(self._status)

    @property
    def context(self) -> object:
        return self.rt.context

    def update(self) -> common.Status:
        """py_trees entry point: one BT.CPP-style tick of this node."""
        return _PY_TREES_STATUS[self.execute_tick()]

    # lifecycle --------------------------------------------------------------------------
    def tick(self) -> int:  # type: ignore[override]
        raise NotImplementedError

    def halt(self) -> None:
        self.reset_status()

    def execute_tick(self) -> int:
        try:
            if self._pre is not None:
                st = self._check_pre()
                if st is None:
                    st = self.tick()
            else:
                st = self.tick()
            if st <= RUNNING and (st == IDLE or self.SYNC_ONLY):
                raise self._refused_result(st)
            if self._post is not None and (st == SUCCESS or st == FAILURE):
                self._run_post(st)
        except BTError as err:
            self._attribute(err)
            raise
        except Exception as err:  # noqa: BLE001 - a plugin's error is attributed to its node path
            raise self._plugin_error(err) from err
        if st != SKIPPED:
            prev = self._status
            if prev != st:
                self._status = st
                if st >= SUCCESS:
                    self.last_result = st
                obs = self.rt.observer
                if obs is not None:
                    obs(self, prev, st)
        return st

    def execute_tick_hooked(self) -> int:
        """`execute_tick` with BT.CPP's injected pre- and post-tick callbacks (`executeTick` in
        tree_node.cpp), which the Groot2 publisher installs as `self.tick_hooks`: the pre-tick one
        runs after the pre-conditions and only while the node is IDLE or RUNNING, and a SUCCESS or
        FAILURE it returns replaces `tick()`; the post-tick one runs after the post-conditions
        and a SUCCESS or FAILURE it returns replaces the result. Installed on the instance (as
        `execute_tick`) only while a hook exists, so trees without hooks pay nothing."""
        pre_hook, post_hook = self.tick_hooks
        try:
            st = self._check_pre() if self._pre is not None else None
            if st is None:
                if pre_hook is not None and self._status <= RUNNING:
                    forced = pre_hook(self)
                    if forced == SUCCESS or forced == FAILURE:
                        st = forced
                if st is None:
                    st = self.tick()
                    if st <= RUNNING and (st == IDLE or self.SYNC_ONLY):
                        raise self._refused_result(st)
            if self._post is not None and (st == SUCCESS or st == FAILURE):
                self._run_post(st)
            if post_hook is not None:
                forced = post_hook(self, st)
                if forced == SUCCESS or forced == FAILURE:
                    st = forced
        except BTError as err:
            self._attribute(err)
            raise
        except Exception as err:  # noqa: BLE001 - a plugin's error is attributed to its node path
            raise self._plugin_error(err) from err
        if st != SKIPPED:
            self.set_status(st)
        if isinstance(self, DecoratorNode):
            child = self.children[0]
            if child._status == SUCCESS or child._status == FAILURE:
                child.reset_status()
        return st

    # The error paths `execute_tick` and `execute_tick_hooked` share (kept out of their hot path).
    def _refused_result(self, st: int) -> BTRuntimeError:
        """The error for a `tick()` that returned IDLE, or RUNNING from a synchronous node."""
        if st == IDLE:
            return BTRuntimeError(
                f"{self.node_id} returned IDLE, which a tick may never return", node_path=self.path
            )
        return BTRuntimeError(
            f"{self.node_id} is synchronous and may not return RUNNING", node_path=self.path
        )

    def _attribute(self, err: BTError) -> None:
        """Gives an error that names no place yet this node's path."""
        if err.node_path is None and err.file is None:
            err.node_path = self.path

    def _plugin_error(self, err: Exception) -> BTRuntimeError:
        """Any other error a node raised (a plugin's), as a BTRuntimeError at this node's path."""
        return BTRuntimeError(f"{type(err).__name__}: {err}", node_path=self.path)

    def set_tick_hooks(
        self, pre_hook: Callable[..., int] | None, post_hook: Callable[..., int] | None
    ) -> None:
        """Installs (or, with two Nones, removes) the injected tick callbacks; see `execute_tick_hooked`."""
        if pre_hook is None and post_hook is None:
            # The tick thread may be entering `execute_tick_hooked` right now: it then reads the
            # class's (None, None) and ticks as usual.
            self.__dict__.pop("execute_tick", None)
            self.__dict__.pop("tick_hooks", None)
            return
        self.tick_hooks = (pre_hook, post_hook)
        self.execute_tick = self.execute_tick_hooked  # type: ignore[method-assign]

    def set_status(self, st: int) -> None:
        prev = self._status
        if prev != st:
            self._status = st
            if st == SUCCESS or st == FAILURE:
                self.last_result = st
            obs = self.rt.observer
            if obs is not None:
                obs(self, prev, st)

    def reset_status(self) -> None:
        prev = self._status
        if prev != IDLE:
            self._status = IDLE
            self._left = prev
            obs = self.rt.observer
            if obs is not None:
                obs(self, prev, IDLE)

    def halt_node(self) -> None:
        self.halt()
        if self._post is not None:
            script = self._post.get("_onHalted")
            if script is not None:
                self._run_script(script, "_onHalted")

    def emit_wake_up(self) -> None:
        self.rt.wake_up()

    def wake_up(self) -> None:
        self.rt.wake_up()

    # pre/post conditions -----------------------------------------------------------------
    def _run_script(self, script: Script, attr: str) -> Any:
        try:
            return script(self._env)
        except ScriptError as err:
            source = self._script_sources.get(attr, "")
            raise BTRuntimeError(
                f"Error in script [{source}] ({attr}): {err.message}", node_path=self.path
            ) from None

    def _check_pre(self) -> int | None:
        status = self._status
        for kind, script in self._pre or ():
            if status == IDLE or status == SKIPPED:
                result = truthy(self._run_script(script, _PRE_NAMES[kind]))
                if result:
                    if kind == 0:
                        return FAILURE
                    if kind == 1:
                        return SUCCESS
                    if kind == 2:
                        return SKIPPED
                elif kind == 3:
                    return SKIPPED
            elif status == RUNNING and kind == 3:
                if not truthy(self._run_script(script, "_while")):
                    self.halt_node()
                    return SKIPPED
        return None

    def _run_post(self, st: int) -> None:
        post = self._post or {}
        key = "_onSuccess" if st == SUCCESS else "_onFailure"
        script = post.get(key)
        if script is not None:
            self._run_script(script, key)
        script = post.get("_post")
        if script is not None:
            self._run_script(script, "_post")


_PRE_NAMES = {0: "_failureIf", 1: "_successIf", 2: "_skipIf", 3: "_while"}


class LeafNode(TreeNode):
    KIND = NodeKind.ACTION


class ControlNode(TreeNode):
    KIND = NodeKind.CONTROL
    SIGNALS_WAKE_UP = True

    def halt(self) -> None:
        self.reset_children()
        self.reset_status()

    def reset_children(self) -> None:
        for child in self.children:
            if child._status == RUNNING:
                child.halt_node()
            child.reset_status()

    def halt_child(self, index: int) -> None:
        child = self.children[index]
        if child._status == RUNNING:
            child.halt_node()
        child.reset_status()

    def halt_children_from(self, first: int) -> None:
        for i in range(first, len(self.children)):
            self.halt_child(i)


class DecoratorNode(TreeNode):
    KIND = NodeKind.DECORATOR
    SIGNALS_WAKE_UP = True

    @property
    def child(self) -> TreeNode:
        return self.children[0]

    @property
    def decorated(self) -> TreeNode:
        return self.children[0]

    def execute_tick(self) -> int:
        st = TreeNode.execute_tick(self)
        child = self.children[0]
        cs = child._status
        if cs == SUCCESS or cs == FAILURE:
            child.reset_status()
        return st

    def halt(self) -> None:
        self.reset_child()
        self.reset_status()

    def reset_child(self) -> None:
        child = self.children[0]
        if child._status == RUNNING:
            child.halt_node()
        child.reset_status()
