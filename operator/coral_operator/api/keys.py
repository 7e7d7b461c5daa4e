"""The wire names of status fields, derived from the API models' aliases.

Status travels as plain dicts (kopf bodies, merge patches, the executor's patches), so its keys
are strings somewhere. They are taken from here: `keys.TREE.root_status` is `"rootStatus"`, the
alias of `TreeState.root_status`. A field that is renamed or removed in the model makes every use
fail (`tests/unit/operator/test_status_keys_are_model_fields.py` finds each use without running
it), instead of writing a key the API server prunes in silence.
"""

from __future__ import annotations

from collections.abc import Iterator

from pydantic import BaseModel

from coral_operator.api.common import Condition
from coral_operator.api.instance import (
    ComponentState,
    CoralInstanceStatus,
    NoProgress,
    PluginState,
    RobotState,
    TreeFailure,
    TreeState,
)
from coral_operator.api.rollout import CanaryStatus, RolledBack, RolloutCounts, RolloutFailure, RolloutStatus
from coral_operator.api.system import CoralSystemStatus, RobotCounts, TreeCounts


class WireNames:
    """The wire names of one model's fields, as attributes named after its Python fields."""

    __slots__ = ("model", "_names")

    def __init__(self, model: type[BaseModel]) -> None:
        self.model = model
        self._names = {name: info.alias or name for name, info in model.model_fields.items()}

    def __getattr__(self, field: str) -> str:
        try:
            return self._names[field]
        except KeyError:
            raise AttributeError(f"{self.model.__name__} has no field {field!r}") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._names.values())


INSTANCE_STATUS = WireNames(CoralInstanceStatus)
TREE = WireNames(TreeState)
TREE_FAILURE = WireNames(TreeFailure)
NO_PROGRESS = WireNames(NoProgress)
PLUGINS = WireNames(PluginState)
ROBOT = WireNames(RobotState)
COMPONENT = WireNames(ComponentState)
SYSTEM_STATUS = WireNames(CoralSystemStatus)
ROBOT_COUNTS = WireNames(RobotCounts)
TREE_COUNTS = WireNames(TreeCounts)
ROLLOUT = WireNames(RolloutStatus)
ROLLOUT_COUNTS = WireNames(RolloutCounts)
CANARY = WireNames(CanaryStatus)
ROLLOUT_FAILURE = WireNames(RolloutFailure)
ROLLED_BACK = WireNames(RolledBack)
CONDITION = WireNames(Condition)
