"""BT.CPP's Groot2 wire format (`groot2_protocol.h`): request and reply headers, error replies, the
status buffer, recorded transitions and hook records. Pure functions and constants; used by the
publisher's server thread and by the Python client (`coral tree watch`, the tests).
"""

from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass
from typing import Any

PROTOCOL_ID = 2
HEADER = struct.Struct("<BBI")  # protocol, request type (an ASCII letter), request id
UUID_SIZE = 16

FULLTREE = ord("T")
STATUS = ord("S")
BLACKBOARD = ord("B")
HOOK_INSERT = ord("I")
HOOK_REMOVE = ord("R")
BREAKPOINT_REACHED = ord("N")
BREAKPOINT_UNLOCK = ord("U")
HOOKS_DUMP = ord("D")
REMOVE_ALL_HOOKS = ord("A")
DISABLE_ALL_HOOKS = ord("X")
TOGGLE_RECORDING = ord("r")
GET_TRANSITIONS = ord("t")
# Requests that change how the tree runs: refused unless the publisher allows hooks.
CHANGING = frozenset({HOOK_INSERT, BREAKPOINT_UNLOCK})
# A status byte for a node back to IDLE: 10 + the status it left.
IDLE_FROM = 10
STATUS_NAMES = {"IDLE": 0, "RUNNING": 1, "SUCCESS": 2, "FAILURE": 3, "SKIPPED": 4}
PRE, POST = 0, 1
BREAKPOINT, REPLACE = 0, 1


class ProtocolError(ValueError):
    """A request the publisher answers with an error reply; the message is the reply's text."""


def new_tree_uuid() -> bytes:
    """A random (version 4) UUID, as BT.CPP's `CreateRandomUUID` makes one per published tree."""
    raw = bytearray(os.urandom(UUID_SIZE))
    raw[6] = (raw[6] & 0x4F) | 0x40
    raw[8] = (raw[8] & 0xBF) | 0x80
    return bytes(raw)


def encode_header(request_type: int, request_id: int) -> bytes:
    return HEADER.pack(PROTOCOL_ID, request_type & 0xFF, request_id & 0xFFFFFFFF)


def decode_header(frame: bytes) -> tuple[int, int, int]:
    """(protocol, request type, request id); a frame that is not exactly 6 bytes is refused."""
    if len(frame) != HEADER.size:
        raise ProtocolError("wrong request header")
    return HEADER.unpack(frame)


def reply_header(request_type: int, request_id: int, tree_uuid: bytes) -> bytes:
    """The request header echoed (protocol forced to 2), then the tree's UUID."""
    return encode_header(request_type, request_id) + tree_uuid


def error_reply(message: str) -> list[bytes]:
    return [b"error", message.encode("utf-8", "replace")]


def encode_status(pairs: list[tuple[int, int]]) -> bytes:
    return b"".join(struct.pack("<HB", uid, code) for uid, code in pairs)


def decode_status(buffer: bytes) -> dict[int, int]:
    """uid -> status byte (IDLE_FROM + s for a node back to IDLE after s)."""
    if len(buffer) % 3:
        raise ProtocolError(f"a status buffer of {len(buffer)} bytes is not made of 3-byte records")
    return {uid: code for uid, code in struct.iter_unpack("<HB", buffer)}


def encode_transition(micros: int, uid: int, status: int) -> bytes:
    return (micros & 0xFFFFFFFFFFFF).to_bytes(6, "little") + struct.pack("<HB", uid, status)


def decode_transitions(buffer: bytes) -> list[tuple[int, int, int]]:
    """(microseconds since recording started, uid, status) per 9-byte record."""
    if len(buffer) % 9:
        raise ProtocolError(f"a transition buffer of {len(buffer)} bytes is not made of 9-byte records")
    return [
        (int.from_bytes(buffer[i : i + 6], "little"), *struct.unpack_from("<HB", buffer, i + 6))
        for i in range(0, len(buffer), 9)
    ]


@dataclass
class HookRecord:
    """One hook as Groot2 sends it (`Monitor::Hook` in JSON)."""

    uid: int
    position: int = PRE
    mode: int = BREAKPOINT
    enabled: bool = True
    once: bool = False
    desired_status: int = 4  # SKIPPED: tick the node as usual

    def as_json(self) -> dict[str, Any]:
        names = {v: k for k, v in STATUS_NAMES.items()}
        return {
            "enabled": self.enabled,
            "uid": self.uid,
            "mode": self.mode,
            "once": self.once,
            "desired_status": names[self.desired_status],
            "position": self.position,
        }


def _field(record: Any, key: str, kind: type | tuple[type, ...]) -> Any:
    if not isinstance(record, dict):
        raise ProtocolError("a hook must be a JSON object")
    if key not in record:
        raise ProtocolError(f"a hook needs the key [{key}]")
    value = record[key]
    # JSON true is no number here, and a number no bool: nlohmann's get<> refuses both.
    if isinstance(value, bool) != (kind is bool) or not isinstance(value, kind):
        raise ProtocolError(f"the hook's [{key}] has the wrong type")
    return value


def parse_json(payload: bytes) -> Any:
    try:
        return json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as err:
        raise ProtocolError(f"the payload is not JSON: {err}") from None


def _uid(record: Any) -> int:
    uid = _field(record, "uid", int)
    if not 0 <= uid <= 0xFFFF:
        raise ProtocolError("the hook's [uid] is not a uint16")
    return uid


def _position(record: Any) -> int:
    position = _field(record, "position", int)
    if position not in (PRE, POST):
        raise ProtocolError("the hook's [position] must be 0 (pre) or 1 (post)")
    return position


def parse_hook(record: Any) -> HookRecord:
    """A hook from its JSON object (`from_json` in groot2_protocol.h): every key is required."""
    mode = _field(record, "mode", int)
    if mode not in (BREAKPOINT, REPLACE):
        raise ProtocolError("the hook's [mode] must be 0 (breakpoint) or 1 (replace)")
    status = _field(record, "desired_status", str)
    if status not in STATUS_NAMES:
        raise ProtocolError(f"cannot convert '{status}' to NodeStatus")
    return HookRecord(
        uid=_uid(record),
        position=_position(record),
        mode=mode,
        enabled=_field(record, "enabled", bool),
        once=_field(record, "once", bool),
        desired_status=STATUS_NAMES[status],
    )


def parse_hooks(payload: bytes) -> list[HookRecord]:
    """One hook or an array of hooks."""
    data = parse_json(payload)
    return [parse_hook(item) for item in (data if isinstance(data, list) else [data])]


def parse_unlock(payload: bytes) -> tuple[int, int, int, bool]:
    """(uid, position, status, remove) of a breakpoint unlock: SUCCESS or FAILURE forces that
    result, anything else continues with the node's own tick (SKIPPED)."""
    record = parse_json(payload)
    uid = _uid(record)
    text = _field(record, "desired_status", str)
    position = _position(record)
    remove = _field(record, "remove_when_done", bool)
    return uid, position, {"SUCCESS": 2, "FAILURE": 3}.get(text, 4), remove


def parse_hook_address(payload: bytes) -> tuple[int, int]:
    """(uid, position) of a hook removal."""
    record = parse_json(payload)
    return _uid(record), _position(record)
