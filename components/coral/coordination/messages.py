"""Wire format of coordination messages (JSON in `std_msgs/String`) and their topics. Pure.

Used by `hub` on both ends; every message carries a unique `id`, so retransmissions and the
replay of transient-local history are recognised and not counted twice.
"""

from __future__ import annotations

import json
import uuid
from dataclasses import asdict, dataclass

from coral_core import parsing

TRIGGER_TOPIC = "/coral/coordination/triggers"
ACK_TOPIC = "/coral/coordination/acks"
VALUE_TOPIC = "/coral/coordination/values"
# How many past messages a late-joining executor receives (transient-local history).
HISTORY_DEPTH = 100
ANY_HOST = "*"


def new_id() -> str:
    return uuid.uuid4().hex


@dataclass(frozen=True)
class Trigger:
    id: str
    sender: str
    target: str
    process: str


@dataclass(frozen=True)
class Ack:
    id: str
    sender: str


@dataclass(frozen=True)
class SharedValue:
    id: str
    sender: str
    target: str
    key: str
    value: str
    stamp: float


def encode(message: Trigger | Ack | SharedValue) -> str:
    return json.dumps(asdict(message), separators=(",", ":"))


def decode_trigger(text: str) -> Trigger | None:
    try:
        raw = parsing.load_json(text)
        return Trigger(str(raw["id"]), str(raw["sender"]), str(raw["target"]), str(raw["process"]))
    except (ValueError, KeyError, TypeError):
        return None


def decode_ack(text: str) -> Ack | None:
    try:
        raw = parsing.load_json(text)
        return Ack(str(raw["id"]), str(raw["sender"]))
    except (ValueError, KeyError, TypeError):
        return None


def decode_value(text: str) -> SharedValue | None:
    try:
        raw = parsing.load_json(text)
        return SharedValue(
            str(raw["id"]),
            str(raw["sender"]),
            str(raw["target"]),
            str(raw["key"]),
            str(raw["value"]),
            float(raw["stamp"]),
        )
    except (ValueError, KeyError, TypeError):
        return None
