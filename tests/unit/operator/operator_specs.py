"""Small, valid CoralSystem specs and observed robots shared by the operator's unit tests."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from coral_operator.planning.observed import RobotNode

TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <AlwaysSuccess/>
    </Sequence>
  </BehaviorTree>
</root>
"""

BASE_SPEC: dict[str, Any] = {
    "robots": {"matchLabels": {"fleet": "a"}},
    "parameters": {"inline": "driver:\n  ros__parameters:\n    rate: 10\n"},
    "tree": {"inline": TREE},
    "drivers": [{"name": "lidar", "image": "example/lidar:1"}],
    "skillsets": [{"name": "slam", "image": "example/slam:1"}],
    "executors": [{"name": "executor", "image": "example/executor:1"}],
}

NOW = datetime(2026, 1, 1, 12, 0, 0, tzinfo=UTC)


def robot(name: str, ready: bool = True, **labels: str) -> RobotNode:
    return RobotNode(
        node_name=name,
        robot=name,
        labels={"coral.dev/robot": name, "fleet": "a", **labels},
        ready=ready,
        last_seen=NOW,
        reachable=ready,
    )
