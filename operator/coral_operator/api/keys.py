"""The wire names of every status field the operator reads or writes, derived from the models' aliases.

The CoralInstance's tables are the contract's (`coral_core.keys`, shared with the executor's status
sink) and are re-exported here; the CoralSystem's and its rollout's are the operator's own. Every
use is checked against its model by `tests/unit/operator/test_status_keys_are_model_fields.py`.
"""

from __future__ import annotations

from coral_core.keys import (
    COMPONENT,
    CONDITION,
    INSTANCE_STATUS,
    NO_PROGRESS,
    PLUGINS,
    ROBOT,
    TREE,
    TREE_FAILURE,
    TREE_HALT,
    WireNames,
)

from coral_operator.api.rollout import CanaryStatus, RolledBack, RolloutCounts, RolloutFailure, RolloutStatus
from coral_operator.api.system import CoralSystemStatus, RobotCounts, TreeCounts

__all__ = [
    "CANARY",
    "COMPONENT",
    "CONDITION",
    "INSTANCE_STATUS",
    "NO_PROGRESS",
    "PLUGINS",
    "ROBOT",
    "ROBOT_COUNTS",
    "ROLLED_BACK",
    "ROLLOUT",
    "ROLLOUT_COUNTS",
    "ROLLOUT_FAILURE",
    "SYSTEM_STATUS",
    "TREE",
    "TREE_COUNTS",
    "TREE_FAILURE",
    "TREE_HALT",
    "WireNames",
]

SYSTEM_STATUS = WireNames(CoralSystemStatus)
ROBOT_COUNTS = WireNames(RobotCounts)
TREE_COUNTS = WireNames(TreeCounts)
ROLLOUT = WireNames(RolloutStatus)
ROLLOUT_COUNTS = WireNames(RolloutCounts)
CANARY = WireNames(CanaryStatus)
ROLLOUT_FAILURE = WireNames(RolloutFailure)
ROLLED_BACK = WireNames(RolledBack)
