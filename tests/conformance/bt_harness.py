"""Differential harness: runs the same XML with scripted stubs in real BT.CPP (behaviortreepy) and in
coral_core.bt, returning per-tick root statuses and the per-node transition stream of each engine.

BT.CPP's transitions come from its own FileLogger (.btlog, format "BTCPP4-FileLogger2": header, uint32
XML length, the instantiated tree as XML with `_uid`s, uint64 start time, then 9-byte records of
6-byte relative microseconds, uint16 uid, uint8 new status).
"""

from __future__ import annotations

import functools
import os
import re
import struct
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import behaviortreepy as btpy
import coral_core.bt as bt
from coral_core.bt.leaves import ConditionNode, StatefulAction, SyncAction
from coral_core.bt.nodes.base import DecoratorNode

BTCPP_STATUS = {
    btpy.NodeStatus.IDLE: 0,
    btpy.NodeStatus.RUNNING: 1,
    btpy.NodeStatus.SUCCESS: 2,
    btpy.NodeStatus.FAILURE: 3,
    btpy.NodeStatus.SKIPPED: 4,
}
TO_BTCPP = {v: k for k, v in BTCPP_STATUS.items()}
ERROR = "ERROR"


def bundled_btcpp_version() -> str:
    """The BT.CPP release compiled into behaviortreepy, read from the version string in the binary."""
    import glob
    import re

    so = glob.glob(os.path.join(os.path.dirname(btpy.__file__), "_behaviortreepy*.so"))[0]
    with open(so, "rb") as fh:
        data = fh.read()
    found = re.findall(rb"\x00(4\.\d+\.\d+)\x00", data)
    return found[0].decode() if found else "unknown"


@dataclass
class Outcomes:
    """Scripted results per stub instance name; each call takes the next one, cycling."""

    scripts: dict[str, list[int]]
    cursor: dict[str, int] = field(default_factory=dict)
    halts: list[str] = field(default_factory=list)
    calls: list[tuple[str, tuple[tuple[str, str], ...]]] | None = None  # set to a list to record

    def next(self, name: str) -> int:
        seq = self.scripts.get(name) or [2]
        i = self.cursor.get(name, 0)
        self.cursor[name] = i + 1
        return seq[i % len(seq)]


@dataclass
class Run:
    verdict: str  # "LOADED", "REJECT" or "TICKERR"
    statuses: list[object]
    transitions: list[tuple[int, int]]
    error: str = ""
    # With `observe=True`: per tick, the leaf calls (name and the local entries of the blackboard
    # the leaf sees, i.e. its subtree's) and the root blackboard after the tick; then haltTree().
    calls: list[list[tuple[str, tuple[tuple[str, str], ...]]]] = field(default_factory=list)
    boards: list[dict[str, str]] = field(default_factory=list)
    halted: list[str] = field(default_factory=list)
    after_halt: dict[str, str] = field(default_factory=dict)
    # Ticks after haltTree(): the tree must start over as BT.CPP's does (statuses, boards).
    restarted: list[tuple[object, dict[str, str]]] = field(default_factory=list)

    def trace(self, with_transitions: bool = True) -> tuple[object, ...]:
        return (
            self.verdict,
            error_site(self.error) if self.verdict == "TICKERR" else None,
            self.statuses,
            self.transitions if with_transitions else None,
            self.calls,
            self.boards,
            self.halted,
            self.after_halt,
            self.restarted,
        )


EMPTY_TEXT = "<empty>"
OBJECT_TEXT = "<object>"  # a queue or another value BT.CPP cannot print as text
RESTART_TICKS = 3
TRACE_FIELDS = (
    "verdict",
    "error site",
    "statuses",
    "transitions",
    "calls",
    "boards",
    "halted",
    "after_halt",
    "restarted",
)
_SCRIPT_ERROR = re.compile(r"Error in script \[(.*?)\]", re.DOTALL)
# BT.CPP 4.8 names no node in a runtime error, so an error is located by the script that raised it
# (its text, which the generator draws per node) and by its cause. BT.CPP wraps only its own
# RuntimeErrors with the script's text: for the causes raised as std::runtime_error (Any casts and
# conversions) the cause alone is compared.
_UNWRAPPED_CAUSES = (
    "Any failed string to number conversion",
    "Invalid floating point to integer conversion",
    "convertFromString",
    "Any::cast failed because it is empty",
    "Any::copyInto fails",
    "stod",
    "ExprUnaryArithmetic: undefined",
    "no known safe conversion",
    "Implicit casting to bool",
    "Loss of precision",
)
_CAUSES = (
    "Missing parameter",
    "Variable not found",
    "not initialized",
    "doesn't exist",
    "Operation not permitted",
    "Invalid operator",
    "can't be converted",
    "can't convert to",
    "Can't convert string",
    "once declared",
    "Can't find the port",
    "Can't mix different types",
    "Logic operators are not allowed",
)


def error_site(message: str) -> tuple[str, str]:
    if "Missing parameter [" in message:
        # BT.CPP names only the port; the engine adds why the value did not convert.
        return ("", "Missing parameter")
    cause = next((c for c in _UNWRAPPED_CAUSES if c in message), "")
    if cause:
        return ("", cause)
    found = _SCRIPT_ERROR.search(message)
    cause = next((c for c in _CAUSES if c in message), "other")
    return (found.group(1) if found else "", cause)


_NUMERIC_TEXT = re.compile(r"-?(?:[0-9]+(?:\.[0-9]+)?|inf|nan)")


@functools.cache
def _probe_factory() -> btpy.BehaviorTreeFactory:
    return btpy.BehaviorTreeFactory()


def _is_text_entry(board: btpy.Blackboard, key: str) -> bool:
    """Does this entry hold text? Asked of BT.CPP itself: `key + 0` is "not permitted" for a string.

    An int beyond 2^53 is refused too, for the precision a double would lose; that entry is a number.
    """
    probe = (
        f'<root BTCPP_format="4"><BehaviorTree ID="Probe"><Script code="{key} + 0"/></BehaviorTree></root>'
    )
    tree = _probe_factory().create_tree_from_text(probe, board)
    try:
        tree.tick_exactly_once()
    except Exception as error:  # noqa: BLE001 - BT.CPP's RuntimeError, whose message tells why
        return "Operation not permitted" in str(error)
    return False


def typed_text(text: str, is_text: bool) -> str:
    """The value as printed, with text that reads like a number quoted so "2" and 2 differ."""
    return f"'{text}'" if is_text and _NUMERIC_TEXT.fullmatch(text) else text


def btcpp_board_text(board: btpy.Blackboard) -> dict[str, str]:
    """Every local entry as `std::to_string` prints it (so 2 and 2.0 differ: "2" vs "2.000000"),
    numeric-looking text quoted."""
    out = {}
    for key in board.get_keys():
        try:
            text = board.get_string(key)
        except Exception as err:  # noqa: BLE001 - an empty entry, or one that is no number or text
            out[key] = EMPTY_TEXT if "hasn't been initialized" in str(err) else OBJECT_TEXT
            continue
        numeric = _NUMERIC_TEXT.fullmatch(text) is not None
        out[key] = typed_text(text, numeric and _is_text_entry(board, key))
    return dict(sorted(out.items()))


def coral_board_text(board: bt.Blackboard) -> dict[str, str]:
    from coral_core.bt.anyvalue import EMPTY, std_to_string

    out = {}
    for key in board.keys():
        value = board.storage[key].value
        if value is EMPTY:
            out[key] = EMPTY_TEXT
        elif isinstance(value, (int, float, str)):
            out[key] = typed_text(std_to_string(value), isinstance(value, str))
        else:
            out[key] = OBJECT_TEXT
    return dict(sorted(out.items()))


# ----------------------------------------------------------------------------------------- BT.CPP
def _read_btlog(path: str) -> list[tuple[int, int]]:
    with open(path, "rb") as fh:
        data = fh.read()
    header = b"BTCPP4-FileLogger2"
    assert data.startswith(header), "unexpected .btlog header"
    # One byte after the magic string, then the uint32 length of the XML description.
    (xml_len,) = struct.unpack_from("<I", data, len(header) + 1)
    offset = len(header) + 1 + 4 + xml_len + 8
    out = []
    while offset + 9 <= len(data):
        uid, status = struct.unpack_from("<HB", data, offset + 6)
        out.append((uid, status & 0x0F))
        offset += 9
    return out


def run_btcpp(
    xml_text: str | None,
    outcomes: Outcomes,
    ticks: int,
    *,
    mode: str = "exactly_once",
    file: str | None = None,
    main_tree: str | None = None,
    leaf_ids: tuple[str, ...] = ("Leaf",),
    cond_ids: tuple[str, ...] = ("Cond",),
    deco_ids: tuple[str, ...] = (),
    host_vars: dict[str, object] | None = None,
    log_transitions: bool = True,
    batch: list[_Pending] | None = None,
    observe: bool = False,
) -> Run:
    if observe:
        outcomes.calls = []
    factory = btcpp_stub_factory(outcomes, leaf_ids, cond_ids, deco_ids)
    board = btcpp_blackboard(host_vars) if host_vars else None
    try:
        tree = build_btcpp_tree(factory, board, xml_text, file, main_tree)
    except Exception as err:  # noqa: BLE001 - any load failure is the REJECT verdict
        return Run("REJECT", [], [], str(err))
    fd, log_path = tempfile.mkstemp(suffix=".btlog")
    os.close(fd)
    logger = btpy.FileLogger(tree, log_path) if log_transitions else None
    statuses: list[object] = []
    verdict, error = "LOADED", ""
    tick = tree.tick_exactly_once if mode == "exactly_once" else tree.tick_once
    run = Run(verdict, statuses, [], error)
    for _ in range(ticks):
        try:
            statuses.append(BTCPP_STATUS[tick()])
        except Exception as err:  # noqa: BLE001 - a tick exception is compared as a verdict
            statuses.append(ERROR)
            run.verdict, run.error = "TICKERR", str(err)
        if observe:
            run.calls.append(list(outcomes.calls or []))
            (outcomes.calls or []).clear()
            run.boards.append(btcpp_board_text(tree.root_blackboard()))
        if run.verdict == "TICKERR":
            break
    if observe:
        outcomes.halts.clear()
        try:
            tree.halt_tree()
        except Exception as err:  # noqa: BLE001 - an _onHalted script may throw
            run.halted.append(ERROR)
            run.error = run.error or str(err)
        run.halted[:0] = list(outcomes.halts)
        run.after_halt = btcpp_board_text(tree.root_blackboard())
        if run.verdict == "LOADED" and not run.halted[-1:] == [ERROR]:
            for _ in range(RESTART_TICKS):
                try:
                    status: object = BTCPP_STATUS[tick()]
                except Exception:  # noqa: BLE001 - compared as a status
                    status = ERROR
                run.restarted.append((status, btcpp_board_text(tree.root_blackboard())))
                if status == ERROR:
                    break
    pending = _Pending(logger, tree, log_path, run)
    if batch is not None:
        batch.append(pending)
    else:
        finish_batch([pending])
    return run


def btcpp_stub_factory(
    outcomes: Outcomes,
    leaf_ids: tuple[str, ...] = ("Leaf",),
    cond_ids: tuple[str, ...] = ("Cond",),
    deco_ids: tuple[str, ...] = (),
) -> btpy.BehaviorTreeFactory:
    """BT.CPP's counterpart of `stub_registry`: leaves and conditions answer from `outcomes` (and
    record their calls while `outcomes.calls` is a list), decorators pass their child's status on."""
    factory = btpy.BehaviorTreeFactory()

    def on_start(node: btpy.TreeNode) -> btpy.NodeStatus:
        if outcomes.calls is not None:
            outcomes.calls.append((node.name(), tuple(btcpp_board_text(node.config().blackboard).items())))
        return TO_BTCPP[outcomes.next(node.name())]

    def on_halted(node: btpy.TreeNode) -> None:
        outcomes.halts.append(node.name())

    for leaf in leaf_ids:
        factory.register_simple_stateful_action(leaf, on_start, on_start, on_halted)
    for cond in cond_ids:
        factory.register_simple_condition(cond, on_start)
    for deco in deco_ids:
        factory.register_simple_decorator(deco, lambda status, node: status)
    return factory


def btcpp_blackboard(host_vars: dict[str, object]) -> btpy.Blackboard:
    """A BT.CPP blackboard holding `host_vars`, each with the C++ type of its Python value."""
    board = btpy.Blackboard.create()
    for k, v in host_vars.items():
        if isinstance(v, bool):
            board.set_bool(k, v)
        elif isinstance(v, int):
            board.set_int(k, v)
        elif isinstance(v, float):
            board.set_double(k, v)
        else:
            board.set_string(k, str(v))
    return board


def build_btcpp_tree(
    factory: btpy.BehaviorTreeFactory,
    board: btpy.Blackboard | None,
    xml_text: str | None,
    file: str | None = None,
    main_tree: str | None = None,
) -> btpy.Tree:
    """`main_tree` of the file or text, else the file's or the text's main tree; raises what BT.CPP
    raises for a tree it refuses."""
    if main_tree is not None:
        if file is not None:
            # behaviortreepy cannot convert a path argument; the text suffices (no includes there).
            factory.register_behavior_tree_from_text(Path(file).read_text(encoding="utf-8"))
        else:
            factory.register_behavior_tree_from_text(xml_text or "")
        return factory.create_tree(main_tree, board)
    if file is not None:
        return factory.create_tree_from_file(file, board)
    return factory.create_tree_from_text(xml_text or "", board)


@dataclass
class _Pending:
    logger: object
    tree: object
    path: str
    run: Run


def finish_batch(batch: list[_Pending], settle_s: float = 0.03, deadline_s: float = 5.0) -> None:
    """Collects the transitions of loggers that are still alive.

    The FileLogger's writer thread drains its queue on a 10 ms cycle and its destructor drops whatever
    is still queued, so the files are read only after their sizes stopped changing for settle_s.
    """
    import time

    end = time.monotonic() + deadline_s
    sizes = None
    while time.monotonic() < end:
        current = [os.path.getsize(p.path) for p in batch]
        if current == sizes:
            break
        sizes = current
        time.sleep(settle_s)  # polling the files' sizes: the writer thread gives no completion signal
    for p in batch:
        if p.logger is not None:
            p.logger = None  # destroys the C++ logger, closing the file
            p.run.transitions = _read_btlog(p.path)
        p.tree = None
        os.unlink(p.path)
    batch.clear()


# ----------------------------------------------------------------------------------------- coral_core.bt
def stub_registry(
    outcomes: Outcomes,
    leaf_ids: tuple[str, ...] = ("Leaf",),
    cond_ids: tuple[str, ...] = ("Cond",),
    deco_ids: tuple[str, ...] = (),
    sync_leaf_ids: tuple[str, ...] = (),
) -> bt.NodeRegistry:
    registry = bt.NodeRegistry.with_builtins()

    def called(node: bt.TreeNode) -> bt.Status:
        if outcomes.calls is not None:
            outcomes.calls.append((node.name, tuple(coral_board_text(node.board).items())))
        return bt.Status(outcomes.next(node.name))

    class Leaf(StatefulAction):
        def on_start(self) -> bt.Status:
            return called(self)

        def on_running(self) -> bt.Status:
            return called(self)

        def on_halted(self) -> None:
            outcomes.halts.append(self.name)

    class Cond(ConditionNode):
        def tick(self) -> bt.Status:
            return called(self)

    class Sync(SyncAction):
        def tick(self) -> bt.Status:
            return called(self)

    class PassThrough(DecoratorNode):
        def tick(self) -> int:
            return self.children[0].execute_tick()

    for leaf in leaf_ids:
        registry.register(leaf, Leaf)
    for cond in cond_ids:
        registry.register(cond, Cond)
    for sync in sync_leaf_ids:
        registry.register(sync, Sync)
    for deco in deco_ids:
        registry.register(deco, PassThrough)
    return registry


def run_coral(
    xml_text: str | None,
    outcomes: Outcomes,
    ticks: int,
    *,
    mode: str = "exactly_once",
    file: str | None = None,
    main_tree: str | None = None,
    registry: bt.NodeRegistry | None = None,
    host_vars: dict[str, object] | None = None,
    prepare: Callable[[bt.Tree], None] | None = None,
    observe: bool = False,
) -> Run:
    if observe:
        outcomes.calls = []
    registry = registry or stub_registry(outcomes)
    transitions: list[tuple[int, int]] = []
    try:
        if file is not None:
            doc = bt.load_tree_file(file, registry, main_tree=main_tree)
        else:
            doc = bt.load_tree_text(xml_text or "", registry, main_tree=main_tree)
        tree = bt.build_tree(doc, registry, blackboard=dict(host_vars or {}))
    except bt.BTLoadError as err:
        return Run("REJECT", [], [], str(err))
    tree.add_transition_listener(lambda t: transitions.append((t.uid, int(t.status))))
    if prepare is not None:
        prepare(tree)
    tick = tree.tick_exactly_once if mode == "exactly_once" else tree.tick_once
    run = Run("LOADED", [], transitions)
    for _ in range(ticks):
        try:
            run.statuses.append(int(tick()))
        except bt.BTRuntimeError as err:
            run.statuses.append(ERROR)
            run.verdict, run.error = "TICKERR", str(err)
        if observe:
            run.calls.append(list(outcomes.calls or []))
            (outcomes.calls or []).clear()
            run.boards.append(coral_board_text(tree.root_blackboard))
        if run.verdict == "TICKERR":
            break
    if observe:
        outcomes.halts.clear()
        try:
            tree.halt()
        except bt.BTRuntimeError as err:
            run.halted.append(ERROR)
            run.error = run.error or str(err)
        run.halted[:0] = list(outcomes.halts)
        run.after_halt = coral_board_text(tree.root_blackboard)
        if run.verdict == "LOADED" and not run.halted[-1:] == [ERROR]:
            for _ in range(RESTART_TICKS):
                try:
                    status: object = int(tick())
                except bt.BTRuntimeError:
                    status = ERROR
                run.restarted.append((status, coral_board_text(tree.root_blackboard)))
                if status == ERROR:
                    break
    return run
