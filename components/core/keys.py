"""The wire names of the CoralInstance's status fields, derived from the contract models' aliases.

Status travels as plain dicts (kopf bodies, merge patches, the executor's patches), so its keys
are strings somewhere. They are taken from here: `keys.TREE.root_status` is `"rootStatus"`, the
alias of `TreeState.root_status`. A field that is renamed or removed in the model makes every use
fail (`tests/unit/operator/test_status_keys_are_model_fields.py` finds each use without running
it), instead of writing a key the API server prunes in silence. The operator's own kinds add their
tables in `coral_operator.api.keys`.
"""

from __future__ import annotations

from collections.abc import Iterator

from coral_core import halt, instance_status, wire
from pydantic import BaseModel


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


INSTANCE_STATUS = WireNames(instance_status.CoralInstanceStatus)
TREE = WireNames(instance_status.TreeState)
TREE_FAILURE = WireNames(instance_status.TreeFailure)
NO_PROGRESS = WireNames(instance_status.NoProgress)
TREE_HALT = WireNames(instance_status.TreeHalt)
HALT = WireNames(halt.HaltRequest)
PLUGINS = WireNames(instance_status.PluginState)
ROBOT = WireNames(instance_status.RobotState)
COMPONENT = WireNames(instance_status.ComponentState)
CONDITION = WireNames(wire.Condition)
