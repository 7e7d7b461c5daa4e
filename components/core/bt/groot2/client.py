"""A Groot2 protocol client over one ZeroMQ REQ socket (and a SUB socket for reached hooks): what
`coral tree watch` draws from and what the differential tests drive both BT.CPP's publisher and
ours with. A timed-out request rebuilds the REQ socket (it cannot be reused after one).
"""

from __future__ import annotations

import json
import random
import xml.etree.ElementTree as ET
from typing import Any

import msgpack
import zmq
from coral_core.bt.groot2 import protocol as p


class Groot2Error(RuntimeError):
    """The publisher answered with an error reply, or did not answer in time."""


class Groot2Client:
    def __init__(self, host: str = "127.0.0.1", port: int = 1667, timeout_s: float = 2.0) -> None:
        self.host = host
        self.port = port
        self.timeout_ms = int(timeout_s * 1000)
        self.context = zmq.Context.instance()
        self.tree_uuid = b""
        self._req = self._new_req()
        self._sub: zmq.Socket | None = None

    def _new_req(self) -> zmq.Socket:
        socket = self.context.socket(zmq.REQ)
        socket.setsockopt(zmq.LINGER, 0)
        socket.setsockopt(zmq.RCVTIMEO, self.timeout_ms)
        socket.setsockopt(zmq.SNDTIMEO, self.timeout_ms)
        socket.connect(f"tcp://{self.host}:{self.port}")
        return socket

    def request(self, kind: int, payload: bytes | None = None) -> list[bytes]:
        """The reply's frames after the header; raises Groot2Error on an error reply."""
        request_id = random.getrandbits(32)
        frames = [p.encode_header(kind, request_id)] + ([payload] if payload is not None else [])
        try:
            self._req.send_multipart(frames)
            reply = self._req.recv_multipart()
        except zmq.ZMQError as err:
            self._req.close(linger=0)
            self._req = self._new_req()
            raise Groot2Error(f"no answer from {self.host}:{self.port} ({err})") from None
        if reply and reply[0] == b"error":
            raise Groot2Error(reply[1].decode("utf-8", "replace") if len(reply) > 1 else "error")
        head = reply[0]
        if len(head) != p.HEADER.size + p.UUID_SIZE or p.HEADER.unpack(head[: p.HEADER.size])[1:] != (
            kind,
            request_id,
        ):
            raise Groot2Error("the reply's header does not match the request")
        self.tree_uuid = head[p.HEADER.size :]
        return reply[1:]

    def fulltree(self) -> str:
        return self.request(p.FULLTREE)[0].decode()

    def status(self) -> dict[int, int]:
        return p.decode_status(self.request(p.STATUS)[0])

    def blackboards(self, names: list[str]) -> Any:
        return msgpack.unpackb(self.request(p.BLACKBOARD, ";".join(names).encode())[0], strict_map_key=False)

    def start_recording(self) -> int:
        return int(self.request(p.TOGGLE_RECORDING, b"start")[0])

    def stop_recording(self) -> None:
        self.request(p.TOGGLE_RECORDING, b"stop")

    def transitions(self) -> list[tuple[int, int, int]]:
        return p.decode_transitions(self.request(p.GET_TRANSITIONS)[0])

    def insert_hooks(self, hooks: list[p.HookRecord]) -> None:
        self.request(p.HOOK_INSERT, json.dumps([h.as_json() for h in hooks]).encode())

    def unlock(self, uid: int, status: str, position: int = p.PRE, remove: bool = False) -> None:
        record = {"uid": uid, "desired_status": status, "position": position, "remove_when_done": remove}
        self.request(p.BREAKPOINT_UNLOCK, json.dumps(record).encode())

    def remove_hook(self, uid: int, position: int = p.PRE) -> None:
        self.request(p.HOOK_REMOVE, json.dumps({"uid": uid, "position": position}).encode())

    def hooks(self) -> list[dict]:
        return json.loads(self.request(p.HOOKS_DUMP)[0])

    def remove_all_hooks(self) -> None:
        self.request(p.REMOVE_ALL_HOOKS)

    def disable_all_hooks(self) -> None:
        self.request(p.DISABLE_ALL_HOOKS)

    def next_breakpoint(self, timeout_s: float) -> int | None:
        """The uid of the next reached hook the publisher announces, or None after timeout_s."""
        if self._sub is None:
            self._sub = self.context.socket(zmq.SUB)
            self._sub.setsockopt(zmq.LINGER, 0)
            self._sub.setsockopt(zmq.SUBSCRIBE, b"")
            self._sub.connect(f"tcp://{self.host}:{self.port + 1}")
        if not self._sub.poll(int(timeout_s * 1000)):
            return None
        frames = self._sub.recv_multipart()
        return int(frames[1]) if len(frames) > 1 else None

    def close(self) -> None:
        self._req.close(linger=0)
        if self._sub is not None:
            self._sub.close(linger=0)

    def __enter__(self) -> Groot2Client:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def parse_fulltree(xml_text: str) -> ET.Element:
    return ET.fromstring(xml_text)
