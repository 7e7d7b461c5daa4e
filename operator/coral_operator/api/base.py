"""Shared pydantic configuration for the CRD models: camelCase on the wire, docstrings as descriptions.

Every model in `api/` derives from `CamelModel`, so the same class parses a custom resource's body
(`model_validate`), renders it back (`to_wire`) and produces the CRD schema (`api.crdgen`).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict
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
