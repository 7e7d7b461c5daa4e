"""What every coral.dev model is built on: camelCase on the wire, docstrings as descriptions, and
the `metav1.Condition` shape both kinds' statuses hold.

Every model in `coral_operator.api` and `coral_core.instance_status` derives from `CamelModel`, so
the same class parses a custom resource's body (`model_validate`), renders it back (`to_wire`) and
produces the CRD schema (`coral_operator.api.crdgen`).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic.alias_generators import to_camel


class CamelModel(BaseModel):
    """Base for every CRD model: camelCase aliases, unknown fields refused, docstrings kept."""

    model_config = ConfigDict(
        alias_generator=to_camel,
        populate_by_name=True,
        use_attribute_docstrings=True,
        extra="forbid",
        frozen=False,
    )

    def to_wire(self) -> dict[str, Any]:
        """The JSON-ready dict as the API server stores it (aliases, unset optionals dropped)."""
        return self.model_dump(mode="json", by_alias=True, exclude_none=True)

    def to_patch(self) -> dict[str, Any]:
        """The fields that were set, by wire name, a None among them included: the body of a merge
        patch, in which a null clears the field it names."""
        return self.model_dump(mode="json", by_alias=True, exclude_unset=True)


class Condition(CamelModel):
    """A `metav1.Condition`: one aspect of the resource's state."""

    type: str = Field(max_length=316)
    """Condition type, for example `Ready`."""
    status: Literal["True", "False", "Unknown"]
    """Whether the condition holds."""
    reason: str = Field(max_length=1024)
    """CamelCase reason for the last transition."""
    message: str = Field(default="", max_length=32768)
    """Human-readable details."""
    observed_generation: int | None = Field(default=None, ge=0)
    """The resource generation the condition was computed from."""
    last_transition_time: str
    """When the status last changed (RFC 3339)."""
