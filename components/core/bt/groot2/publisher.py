"""Publishes a running tree over BT.CPP's Groot2 protocol: a ZeroMQ REP socket on `port` answers
requests, a PUB socket on `port + 1` announces reached hooks. Groot2, `coral tree watch` and
other readers connect to it.

The tick thread pays next to nothing: every node keeps the status it left when it was last reset
(`TreeNode._left`; the server thread reads the nodes' statuses for STATUS), and only while a client
records transitions does an observer append each one to a bounded deque. One server thread owns
both sockets, answers every request, publishes queued hook notifications and watches the
heartbeat. It answers in paced bursts and its share of the interpreter is capped (a request flood
slows the answers, not the tick); requests are bounded in size, parts and queue length. Hooks that
change how the tree runs are refused with an error reply unless `allow_hooks`.

Used by the executor (`--groot2-port`) and `coral run`; see docs/bt-engine.md for where it
follows BT.CPP 4.10 rather than the 4.8.2 that behaviortreepy bundles.
"""

from __future__ import annotations

import collections
import json
import threading
import time
from typing import TYPE_CHECKING

import zmq
from coral_core.bt.groot2 import protocol as p
from coral_core.bt.groot2.boards import dump_boards
from coral_core.bt.groot2.fulltree import build_fulltree_xml, subtree_instances
from coral_core.bt.groot2.hooks import HookTable
from coral_core.bt.status import IDLE

if TYPE_CHECKING:
    from coral_core.bt.nodes.base import TreeNode
    from coral_core.bt.tree import Tree

DEFAULT_PORT = 1667
MAX_FRAME_BYTES = 64 * 1024  # larger frames make ZeroMQ drop the connection
MAX_PARTS = 8
MAX_TRANSITIONS = 1000  # as BT.CPP keeps
QUEUED_REQUESTS = 64  # per connection; beyond it ZeroMQ stops reading from that connection
POLL_S = 0.02
# `wait_for_client`: how long a client that sets no hook holds the first tick after it came.
WAIT_GRACE_S = 3.0
BURST = 8  # requests answered per wake-up, at most
# Requests answered per second, with bursts of up to BUCKET: Groot2 asks a few times a second,
# a flood is paced, and each wake-up of the server thread (which takes the interpreter from the
# tick thread once, whatever it then answers) serves a burst.
RATE_PER_S = 200.0
BUCKET = 40.0
# The server thread may hold the interpreter this share of the time, at most: after a request that
# took t seconds it rests t * (1 - share) / share before the next one.
SERVER_SHARE = 0.03


class Groot2Publisher:
    """Serves one tree; `close()` (or the context manager) stops the thread and frees the ports."""

    def __init__(
        self,
        tree: Tree,
        port: int = DEFAULT_PORT,
        *,
        host: str = "127.0.0.1",
        allow_hooks: bool = False,
        max_heartbeat_delay_s: float = 5.0,
        server_share: float = SERVER_SHARE,
        rate_per_s: float = RATE_PER_S,
    ) -> None:
        self.tree = tree
        self.port = port
        self.host = host
        self.allow_hooks = allow_hooks
        self.max_heartbeat_delay_s = max_heartbeat_delay_s
        self._rest_factor = (1 - server_share) / server_share
        self._rate = rate_per_s
        self._tokens = BUCKET
        self._refilled = time.monotonic()
        self.tree_uuid = p.new_tree_uuid()
        self.instances = subtree_instances(tree)
        self.by_name = {instance.name: instance for instance in self.instances}
        self.fulltree_xml = build_fulltree_xml(tree, self.instances).encode()
        # The status buffer's records in BT.CPP's order; the server thread fills in the statuses
        # from the nodes themselves when asked, so the tick pays nothing for it.
        self._ordered = [node for instance in self.instances for node in instance.nodes]
        self._status_template = p.encode_status([(node.uid, 0) for node in self._ordered])
        nodes_by_uid = {node.uid: node for node in self._ordered}
        self.recording = False
        self.transitions: collections.deque[tuple[int, int, int]] = collections.deque(maxlen=MAX_TRANSITIONS)
        self._record_start = 0.0
        self._notifications: collections.deque[int] = collections.deque(maxlen=64)
        self.hooks = HookTable(nodes_by_uid, self._notifications.append)
        self.last_request = time.monotonic()
        self.requests = 0  # answered so far
        self.connected = threading.Event()  # set by the first request
        self._connected_at: float | None = None
        self.hooked = threading.Event()  # set by the first hook a client inserts
        self._stop = threading.Event()
        self._context = zmq.Context.instance()
        self._server = self._socket(zmq.REP, port)
        try:
            self._publisher = self._socket(zmq.PUB, port + 1)
        except zmq.ZMQError:
            self._server.close(linger=0)
            raise
        self._thread = threading.Thread(target=self._serve, name=f"groot2-{port}", daemon=True)
        self._thread.start()

    def _socket(self, kind: int, port: int) -> zmq.Socket:
        socket = self._context.socket(kind)
        socket.setsockopt(zmq.LINGER, 0)
        socket.setsockopt(zmq.MAXMSGSIZE, MAX_FRAME_BYTES)
        socket.setsockopt(zmq.RCVHWM, QUEUED_REQUESTS)
        socket.setsockopt(zmq.SNDHWM, QUEUED_REQUESTS)
        socket.setsockopt(zmq.SNDTIMEO, 1000)
        # The kernel's buffer per connection too: what a flooding client queues stays small.
        socket.setsockopt(zmq.RCVBUF, MAX_FRAME_BYTES)
        try:
            socket.bind(f"tcp://{self.host}:{port}")
        except zmq.ZMQError:
            socket.close(linger=0)
            raise
        return socket

    # tick thread ----------------------------------------------------------------------------
    def _on_status(self, node: TreeNode, _previous: int, status: int) -> None:
        """Observes transitions only while a client records them."""
        self.transitions.append((time.monotonic(), node.uid, status))

    # server thread --------------------------------------------------------------------------
    def status_buffer(self) -> bytes:
        """3 bytes per node: uid, then its status, or 10 + the status it left for an IDLE node
        that ran (BT.CPP's IDLE_FROM_*); read from the nodes without stopping the tick."""
        out = bytearray(self._status_template)
        index = 2
        for node in self._ordered:
            status = node._status
            if status == IDLE:
                left = node._left
                status = p.IDLE_FROM + left if left != IDLE else IDLE
            out[index] = status
            index += 3
        return bytes(out)

    def _serve(self) -> None:
        poller = zmq.Poller()
        poller.register(self._server, zmq.POLLIN)
        had_heartbeat = True
        while not self._stop.is_set():
            ready = dict(poller.poll(POLL_S * 1000))
            self._publish_notifications()
            if self._server in ready:
                # Every time this thread takes the interpreter back from the tick thread costs the
                # tick a switch, so queued requests are answered in one go, then it rests.
                # CPU time, not wall time: waiting for the interpreter is not holding it.
                started = time.thread_time()
                handled = 0
                for _ in range(BURST):
                    try:
                        frames = self._server.recv_multipart(zmq.NOBLOCK)
                    except zmq.ZMQError:
                        break
                    self.last_request = time.monotonic()
                    self.requests += 1
                    handled += 1
                    if not self.connected.is_set():
                        self._connected_at = time.monotonic()
                        self.connected.set()
                    reply = self.answer(frames)
                    try:
                        self._server.send_multipart(reply, zmq.NOBLOCK)
                    except zmq.ZMQError:
                        pass  # the client left or reads nothing; REP takes the next request anyway
                self._pace(handled, time.thread_time() - started)
            has_heartbeat = time.monotonic() - self.last_request < self.max_heartbeat_delay_s
            if has_heartbeat != had_heartbeat:
                self.hooks.enable_all(has_heartbeat)
                had_heartbeat = has_heartbeat
        self._publish_notifications()

    def _pace(self, handled: int, spent_s: float) -> None:
        """Rests so that the thread holds the interpreter at most `server_share` of the time and
        answers at most `rate_per_s` requests a second (beyond a burst of BUCKET)."""
        now = time.monotonic()
        self._tokens = min(BUCKET, self._tokens + (now - self._refilled) * self._rate) - handled
        self._refilled = now
        rest = spent_s * self._rest_factor
        if self._tokens < 0:
            rest = max(rest, -self._tokens / self._rate)
        if rest > 0:
            self._stop.wait(rest)

    def _publish_notifications(self) -> None:
        while self._notifications:
            uid = self._notifications.popleft()
            header = p.encode_header(p.BREAKPOINT_REACHED, int.from_bytes(p.new_tree_uuid()[:4], "little"))
            try:
                self._publisher.send_multipart([header, str(uid).encode()], zmq.NOBLOCK)
            except zmq.ZMQError:
                pass

    def answer(self, frames: list[bytes]) -> list[bytes]:
        """The reply to one request; any bad request gets an error reply."""
        try:
            if not frames:
                raise p.ProtocolError("empty request")
            _protocol, kind, request_id = p.decode_header(frames[0])
            if len(frames) > MAX_PARTS:
                raise p.ProtocolError(f"a request has at most {MAX_PARTS} parts")
            head = p.reply_header(kind, request_id, self.tree_uuid)
            return [head, *self._payload(kind, frames)]
        except p.ProtocolError as err:
            return p.error_reply(str(err))
        except Exception as err:  # noqa: BLE001 - no request may stop the server
            return p.error_reply(f"{type(err).__name__}: {err}")

    def _second(self, frames: list[bytes]) -> bytes:
        if len(frames) != 2:
            raise p.ProtocolError("must be 2 parts message")
        return frames[1]

    def _payload(self, kind: int, frames: list[bytes]) -> list[bytes]:
        if kind == p.FULLTREE:
            return [self.fulltree_xml]
        if kind == p.STATUS:
            return [self.status_buffer()]
        if kind == p.BLACKBOARD:
            names = self._second(frames).decode("utf-8", "replace")
            return [dump_boards(names, self.by_name, self.tree.root_blackboard)]
        if kind in p.CHANGING and not self.allow_hooks:
            self._second(frames)
            raise p.ProtocolError("hooks are disabled on this executor (see --groot2-allow-hooks)")
        if kind == p.HOOK_INSERT:
            for record in p.parse_hooks(self._second(frames)):
                self.hooks.insert(record)
            self.hooked.set()
            return []
        if kind == p.BREAKPOINT_UNLOCK:
            if not self.hooks.unlock(*p.parse_unlock(self._second(frames))):
                raise p.ProtocolError("Node ID not found")
            return []
        if kind == p.HOOK_REMOVE:
            if not self.hooks.remove(*p.parse_hook_address(self._second(frames))):
                raise p.ProtocolError("Node ID not found")
            return []
        if kind == p.REMOVE_ALL_HOOKS:
            self.hooks.remove_all()
            return []
        if kind == p.DISABLE_ALL_HOOKS:
            self.hooks.enable_all(False)
            return []
        if kind == p.HOOKS_DUMP:
            return [json.dumps(self.hooks.dump()).encode()]
        if kind == p.TOGGLE_RECORDING:
            command = self._second(frames)
            if command == b"start":
                self.transitions.clear()
                self._record_start = time.monotonic()
                if not self.recording:
                    self.recording = True
                    self.tree.add_status_observer(self._on_status)
                return [str(time.time_ns() // 1000).encode()]
            if command == b"stop" and self.recording:
                self.recording = False
                self.tree.remove_status_observer(self._on_status)
            return []
        if kind == p.GET_TRANSITIONS:
            out = bytearray()
            start = self._record_start
            while self.transitions:
                stamp, uid, status = self.transitions.popleft()
                out += p.encode_transition(int((stamp - start) * 1e6), uid, status)
            return [bytes(out)]
        raise p.ProtocolError("Request not recognized")

    def server_cpu_s(self) -> float:
        """CPU seconds the server thread has used (what it can have taken from the tick thread)."""
        ident = self._thread.ident
        if ident is None or not self._thread.is_alive():
            return 0.0
        return time.clock_gettime(time.pthread_getcpuclockid(ident))

    # lifecycle ------------------------------------------------------------------------------
    def wait_for_client(
        self, timeout_s: float, stop: threading.Event | None = None, grace_s: float = WAIT_GRACE_S
    ) -> bool:
        """Holds the caller (before the first tick) until a client has set a hook, or has been
        connected for grace_s without setting one (it only watches), or `stop` is set, or
        timeout_s passed; True if a client came. Ending at the first request would race the
        client's breakpoints against the mission's first tick."""
        deadline = time.monotonic() + timeout_s
        while not (stop is not None and stop.is_set()) and not self.hooked.is_set():
            now = time.monotonic()
            if self._connected_at is not None and now - self._connected_at >= grace_s:
                break
            if now >= deadline:
                break
            self.hooked.wait(min(deadline - now, 0.05))
        return self.connected.is_set()

    def close(self) -> None:
        if self._stop.is_set():
            return
        if self.recording:
            self.recording = False
            self.tree.remove_status_observer(self._on_status)
        self.hooks.close()
        self._stop.set()
        self._thread.join(timeout=5)
        self._server.close(linger=0)
        self._publisher.close(linger=0)

    def __enter__(self) -> Groot2Publisher:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()
