"""Small models shared by both kinds: label selectors, ConfigMap references, conditions.

Used by `api.system`, `api.instance` and the status helpers in `status/`.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from coral_operator.api.base import CamelModel


class LabelSelectorRequirement(CamelModel):
    """One set-based requirement on a robot Node's labels."""

    key: str = Field(min_length=1, max_length=317)
    """Label key, for example `coral.dev/model`."""
    operator: Literal["In", "NotIn", "Exists", "DoesNotExist"]
    """How the key relates to the values."""
    values: list[str] = Field(default_factory=list, max_length=64)
    """Values for `In` and `NotIn`; empty for `Exists` and `DoesNotExist`."""


class LabelSelector(CamelModel):
    """A Kubernetes label selector over robot Nodes; at least one term is required."""

    match_labels: dict[str, str] = Field(default_factory=dict)
    """Labels a robot Node must carry with exactly these values."""
    match_expressions: list[LabelSelectorRequirement] = Field(default_factory=list, max_length=32)
    """Set-based requirements a robot Node must meet."""


class ConfigMapKeyRef(CamelModel):
    """A key of a ConfigMap in the system's namespace."""

    name: str = Field(min_length=1, max_length=253)
    """ConfigMap name."""
    key: str = Field(min_length=1, max_length=253)
    """Key holding the file's content."""


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
