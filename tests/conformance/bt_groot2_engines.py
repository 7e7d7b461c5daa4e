"""Engine hosts for the Groot2 differential tests: a child process that loads trees with scripted
stubs into real BT.CPP (behaviortreepy's `Groot2Publisher`) or into coral_core.bt (its own publisher),
publishes each on a free port pair and ticks it on command, while the test process talks to the
publisher through one pyzmq client (`coral_core.bt.groot2.client`).

Why a process per engine: a breakpoint in behaviortreepy holds the GIL while it waits, so its
client must live elsewhere; and BT.CPP 4.8.2's publisher takes 100 ms to destroy (its server
thread waits out a receive timeout), so a BT.CPP host keeps every publisher it made and leaves
with `os._exit` after a batch of trees. Never send a malformed request to a 4.8.2 publisher: it
aborts the process.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fixtures.ports import free_port_pair

HERE = Path(__file__).resolve().parent
BTCPP, CORAL = "btcpp", "coral"
# BT.CPP trees a host serves before it is replaced (each keeps its publisher's threads alive).
BTCPP_BATCH = 150


@dataclass
class LoadRequest:
    xml: str
    outcomes: dict[str, list[int]]
    mode: str = "exactly_once"
    host_vars: dict[str, object] = field(default_factory=dict)
    heartbeat_ms: int = 5000
    leaf_ids: tuple[str, ...] = ("Leaf",)
    cond_ids: tuple[str, ...] = ("Cond",)
    deco_ids: tuple[str, ...] = ()
    main_tree: str | None = None
    file: str | None = None  # load this file instead of `xml` (its includes resolve beside it)


# ------------------------------------------------------------------------------- child process
class _BtcppHost:
    def __init__(self) -> None:
        import behaviortreepy as btpy

        self.btpy = btpy
        self.kept: list[tuple[Any, Any]] = []
        self.tree: Any = None
        self.tick: Any = None

    def load(self, req: LoadRequest, port: int) -> tuple[str, Any]:
        from bt_harness import Outcomes, btcpp_blackboard, btcpp_stub_factory, build_btcpp_tree

        factory = btcpp_stub_factory(Outcomes(req.outcomes), req.leaf_ids, req.cond_ids, req.deco_ids)
        board = btcpp_blackboard(req.host_vars)
        try:
            tree = build_btcpp_tree(factory, board, req.xml, req.file, req.main_tree)
        except Exception as err:  # noqa: BLE001 - any load failure is the REJECT verdict
            return "REJECT", str(err)
        while True:
            port = free_port_pair(port)
            try:
                publisher = self.btpy.Groot2Publisher(tree, port)
                break
            except Exception:  # noqa: BLE001 - taken meanwhile: the next pair
                port += 2
        publisher.set_max_heartbeat_delay(req.heartbeat_ms)
        self.kept.append((tree, publisher))
        self.tree = tree
        self.tick = tree.tick_exactly_once if req.mode == "exactly_once" else tree.tick_once
        return "LOADED", port

    def tick_tree(self) -> tuple[str, Any]:
        from bt_harness import BTCPP_STATUS

        try:
            return "status", BTCPP_STATUS[self.tick()]
        except Exception as err:  # noqa: BLE001 - a tick error is compared as a verdict
            return "error", str(err)

    def drop(self) -> None:
        self.tree = self.tick = None


class _CoralHost:
    def __init__(self) -> None:
        self.tree: Any = None
        self.publisher: Any = None

    def load(self, req: LoadRequest, port: int) -> tuple[str, Any]:
        import coral_core.bt as bt
        import zmq
        from bt_harness import Outcomes, stub_registry
        from coral_core.bt.groot2 import Groot2Publisher

        outcomes = Outcomes(req.outcomes)
        registry = stub_registry(outcomes, req.leaf_ids, req.cond_ids, req.deco_ids)
        try:
            if req.file is not None:
                doc = bt.load_tree_file(req.file, registry, main_tree=req.main_tree)
            else:
                doc = bt.load_tree_text(req.xml, registry, main_tree=req.main_tree)
            tree = bt.build_tree(doc, registry, blackboard=dict(req.host_vars))
        except bt.BTLoadError as err:
            return "REJECT", str(err)
        while True:
            port = free_port_pair(port)
            try:
                # The tests read every tick at once: no share cap on the server thread here.
                self.publisher = Groot2Publisher(
                    tree,
                    port,
                    allow_hooks=True,
                    max_heartbeat_delay_s=req.heartbeat_ms / 1000,
                    server_share=1.0,
                    rate_per_s=1e9,
                )
                break
            except zmq.ZMQError:
                port += 2
        self.tree = tree
        self.tick = tree.tick_exactly_once if req.mode == "exactly_once" else tree.tick_once
        return "LOADED", port

    def tick_tree(self) -> tuple[str, Any]:
        import coral_core.bt as bt

        try:
            return "status", int(self.tick())
        except bt.BTRuntimeError as err:
            return "error", str(err)

    def drop(self) -> None:
        if self.publisher is not None:
            self.publisher.close()
        self.tree = self.publisher = None


def _host_main(conn: Any, engine: str) -> None:
    sys.path.insert(0, str(HERE))
    # BT.CPP prints blackboard dumps on stderr when a tree fails to build.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    host: Any = _BtcppHost() if engine == BTCPP else _CoralHost()
    while True:
        command, argument = conn.recv()
        if command == "load":
            request, port = argument
            conn.send(host.load(request, port))
        elif command == "tick":
            conn.send(host.tick_tree())
        elif command == "drop":
            host.drop()
            conn.send(("ok", None))
        elif command == "exit":
            conn.send(("ok", None))
            conn.close()
            os._exit(0)  # BT.CPP's publishers are left to the process's end (see the module doc)


# ------------------------------------------------------------------------------- test process
class EngineHost:
    """The test side of one engine's host process; replaces a BT.CPP host after a batch."""

    def __init__(self, engine: str, first_port: int) -> None:
        self.engine = engine
        self.next_port = first_port
        self.served = 0
        self._context = multiprocessing.get_context("spawn")
        self._start()

    def _start(self) -> None:
        self.conn, child = self._context.Pipe()
        self.process = self._context.Process(target=_host_main, args=(child, self.engine), daemon=True)
        self.process.start()
        child.close()

    # Bounds against a hung host, not a speed limit: a host just spawned imports its engine first,
    # which takes far longer on a machine busy with a kind cluster.
    def _call(self, command: str, argument: Any = None, timeout_s: float = 90.0) -> tuple[str, Any]:
        self.conn.send((command, argument))
        return self.receive(timeout_s)

    def receive(self, timeout_s: float) -> tuple[str, Any]:
        if not self.conn.poll(timeout_s):
            raise TimeoutError(f"the {self.engine} host did not answer within {timeout_s} s")
        return self.conn.recv()

    def load(self, request: LoadRequest) -> tuple[str, Any]:
        if self.engine == BTCPP and self.served >= BTCPP_BATCH:
            self.restart()
        self.served += 1
        verdict, value = self._call("load", (request, self.next_port))
        if verdict == "LOADED":
            self.next_port = value + 2
            if self.next_port > 64000:
                self.next_port = 20000
        return verdict, value

    def tick(self, timeout_s: float = 90.0) -> tuple[str, Any]:
        return self._call("tick", timeout_s=timeout_s)

    def start_tick(self) -> None:
        """A tick whose answer `tick_done` reads later (while the client works a breakpoint)."""
        self.conn.send(("tick", None))

    def tick_done(self, timeout_s: float) -> tuple[str, Any] | None:
        return self.conn.recv() if self.conn.poll(timeout_s) else None

    def drop(self) -> None:
        self._call("drop")

    def restart(self) -> None:
        """A new host process in place of this one, also of a hung one (`close` kills it)."""
        self.close()
        self._start()
        self.served = 0

    def close(self) -> None:
        try:
            self._call("exit", timeout_s=10)
        except (TimeoutError, EOFError, OSError):
            pass
        self.process.join(timeout=10)
        if self.process.is_alive():
            self.process.kill()
