"""Status, node-kind and port-direction enums shared by every module of the behavior-tree engine."""

from __future__ import annotations

from enum import IntEnum, StrEnum


class Status(IntEnum):
    """Node status with BehaviorTree.CPP's numbering (FileLogger2 stores these values)."""

    IDLE = 0
    RUNNING = 1
    SUCCESS = 2
    FAILURE = 3
    SKIPPED = 4


class NodeKind(StrEnum):
    ACTION = "action"
    CONDITION = "condition"
    CONTROL = "control"
    DECORATOR = "decorator"
    SUBTREE = "subtree"


class PortDirection(StrEnum):
    INPUT = "input"
    OUTPUT = "output"
    INOUT = "inout"


IDLE, RUNNING, SUCCESS, FAILURE, SKIPPED = (
    Status.IDLE,
    Status.RUNNING,
    Status.SUCCESS,
    Status.FAILURE,
    Status.SKIPPED,
)


def is_completed(status: int) -> bool:
    return status == SUCCESS or status == FAILURE


def parse_status(text: str) -> Status:
    """Converts a NodeStatus literal as BT.CPP's convertFromString<NodeStatus> does."""
    try:
        return Status[text.strip().upper()]
    except KeyError:
        raise ValueError(f"cannot convert '{text}' to NodeStatus") from None
