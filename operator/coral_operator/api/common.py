"""Small models shared by both kinds: label selectors, ConfigMap references, conditions.

Used by `api.system`, `api.instance` and the status helpers in `status/`.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

from coral_core.wire import CamelModel, Condition
from pydantic import Field, field_validator, model_validator

# Kubernetes label syntax: an optional DNS-subdomain prefix and `/`, then a name of at most 63
# characters; values are empty or such a name.
LABEL_KEY = (
    r"^([a-z0-9]([-a-z0-9]*[a-z0-9])?(\.[a-z0-9]([-a-z0-9]*[a-z0-9])?)*/)?"
    r"[A-Za-z0-9]([-A-Za-z0-9_.]{0,61}[A-Za-z0-9])?$"
)
LABEL_VALUE = r"^(([A-Za-z0-9][-A-Za-z0-9_.]{0,61})?[A-Za-z0-9])?$"
LabelKey = Annotated[str, Field(min_length=1, max_length=317, pattern=LABEL_KEY)]
LabelValue = Annotated[str, Field(max_length=63, pattern=LABEL_VALUE)]

VALUES_NEEDED = "operator In and NotIn need at least one value"
VALUES_FORBIDDEN = "operator Exists and DoesNotExist take no values"
LABELS_SYNTAX = "matchLabels keys and values must be Kubernetes label keys and values"


class LabelSelectorRequirement(CamelModel):
    """One set-based requirement on a robot Node's labels."""

    model_config = CamelModel.model_config | {
        "json_schema_extra": {
            "x-kubernetes-validations": [
                {
                    "rule": "!(self.operator in ['In', 'NotIn']) || size(self.values) > 0",
                    "message": VALUES_NEEDED,
                    "fieldPath": ".values",
                },
                {
                    "rule": "self.operator in ['In', 'NotIn'] || size(self.values) == 0",
                    "message": VALUES_FORBIDDEN,
                    "fieldPath": ".values",
                },
            ]
        }
    }

    key: LabelKey
    """Label key, for example `coral.dev/model`."""
    operator: Literal["In", "NotIn", "Exists", "DoesNotExist"]
    """How the key relates to the values."""
    values: list[LabelValue] = Field(default_factory=list, max_length=64)
    """Values for `In` and `NotIn` (at least one); empty for `Exists` and `DoesNotExist`."""

    @model_validator(mode="after")
    def _values_match_operator(self) -> LabelSelectorRequirement:
        if self.operator in ("In", "NotIn") and not self.values:
            raise ValueError(VALUES_NEEDED)
        if self.operator in ("Exists", "DoesNotExist") and self.values:
            raise ValueError(VALUES_FORBIDDEN)
        return self


def _cel_string(text: str) -> str:
    return "'" + text.replace("\\", "\\\\").replace("'", "\\'") + "'"


class LabelSelector(CamelModel):
    """A Kubernetes label selector over robot Nodes; at least one term is required."""

    # The schema cannot put a pattern on map keys; CEL can.
    model_config = CamelModel.model_config | {
        "json_schema_extra": {
            "x-kubernetes-validations": [
                {
                    "rule": "!has(self.matchLabels) || "
                    f"self.matchLabels.all(k, k.matches({_cel_string(LABEL_KEY)}))",
                    "message": LABELS_SYNTAX,
                    "fieldPath": ".matchLabels",
                }
            ]
        }
    }

    # Keys are checked by the validator below and the CEL rule above: a key pattern here would
    # become `patternProperties`, which a structural schema does not allow.
    match_labels: dict[str, LabelValue] = Field(default_factory=dict, max_length=64)
    """Labels a robot Node must carry with exactly these values."""

    @field_validator("match_labels")
    @classmethod
    def _label_keys(cls, labels: dict[str, str]) -> dict[str, str]:
        for key in labels:
            if not (0 < len(key) <= 317 and re.fullmatch(LABEL_KEY, key)):
                raise ValueError(f"{key!r} is not a Kubernetes label key")
        return labels

    match_expressions: list[LabelSelectorRequirement] = Field(default_factory=list, max_length=32)
    """Set-based requirements a robot Node must meet."""


DNS_SUBDOMAIN = r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?(\.[a-z0-9]([-a-z0-9]*[a-z0-9])?)*$"
"""An object name as the API server admits one (RFC 1123 subdomain)."""
CONFIG_MAP_KEY = r"^[-._a-zA-Z0-9]+$"
"""A ConfigMap key as the API server admits one."""


class ConfigMapKeyRef(CamelModel):
    """A key of a ConfigMap in the system's namespace. The operator reads only a ConfigMap labelled
    `coral.dev/source: "true"`: that label is its owners' consent to have it copied into the
    system's pods, which whoever may write CoralSystems there could not otherwise read."""

    name: str = Field(min_length=1, max_length=253, pattern=DNS_SUBDOMAIN)
    """ConfigMap name; the ConfigMap must carry the label `coral.dev/source: "true"`."""
    key: str = Field(min_length=1, max_length=253, pattern=CONFIG_MAP_KEY)
    """Key holding the file's content."""


READY = "Ready"
"""The condition every kind has: the resource does what its spec asks."""
RECONCILING = "Reconciling"
"""The kstatus condition of work still under way."""
PENDING = "Pending"
"""The reason of the status a new object has before the operator writes one."""
EPOCH = "1970-01-01T00:00:00Z"


def pending_status() -> dict[str, Any]:
    """The status of every new CoralSystem and CoralInstance until the operator writes one.

    The CRDs default `status` to it, so a new object reads as in progress to every client:
    kstatus sees Reconciling=True, Flux's expressions and Argo CD's health check see no
    `observedGeneration`. Without it a new object has no status at all, which kstatus reads as
    Current. It claims nothing more: no `observedGeneration`, since no generation was looked at,
    and transition times at the epoch, which the operator never carries over
    (`status.transitions.written_conditions`).
    """
    message = (
        "No report from the Coral operator yet; a starting robot is reported once it is Ready or "
        "Stalled, or when its start runs long"
    )
    waiting = {"reason": PENDING, "message": message, "last_transition_time": EPOCH}
    conditions = [
        Condition(type=READY, status="Unknown", **waiting),
        Condition(type=RECONCILING, status="True", **waiting),
    ]
    return {"conditions": [condition.to_wire() for condition in conditions]}
