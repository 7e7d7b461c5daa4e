"""The one place that knows how a condition changes over time (metav1.Condition semantics).

Rules: `lastTransitionTime` moves only when `status` flips; `reason`, `message` and
`observedGeneration` are always refreshed; the clock is a parameter. Called by the status builders.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from coral_operator.api import keys
from coral_operator.status.conditions import ConditionType, Reason


@dataclass(frozen=True)
class Verdict:
    """A condition's new value before it meets the old one."""

    type: ConditionType
    status: bool | None
    reason: Reason
    message: str = ""

    @property
    def status_text(self) -> str:
        return "Unknown" if self.status is None else ("True" if self.status else "False")


# Messages quote what users and API servers wrote, which may be long; the schema allows 32768
# characters, and a status the API server refuses would leave the old one in place.
MAX_MESSAGE = 8192


def _bounded(message: str) -> str:
    if len(message) <= MAX_MESSAGE:
        return message
    return message[: MAX_MESSAGE - 30] + f" ... ({len(message)} characters)"


def parse_rfc3339(text: str | None) -> datetime | None:
    """A Kubernetes timestamp (`...Z`) as an aware datetime; None for an empty value."""
    if not text:
        return None
    return datetime.fromisoformat(text.replace("Z", "+00:00"))


def rfc3339(moment: datetime) -> str:
    """Kubernetes' timestamp format, second precision, UTC."""
    return moment.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def written_conditions(status: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The conditions the operator wrote into `status`, which new verdicts are merged with.

    None while `status` is still the CRD's default (`api.common.pending_status`, which has no
    `observedGeneration`; every status the operator writes has one): its epoch transition times
    must not outlive it, so the first written conditions all start now. Both kinds call the field
    alike.
    """
    if written_generation(status) is None:
        return []
    conditions = status.get(keys.INSTANCE_STATUS.conditions)
    if not isinstance(conditions, list):
        return []
    # An executor may write into the status subresource what the schema admits; an entry this
    # module cannot merge with is dropped (and overwritten), never a reason for a pass to fail.
    return [
        c
        for c in conditions
        if isinstance(c, dict)
        and isinstance(c.get(keys.CONDITION.type), str)
        and isinstance(c.get(keys.CONDITION.last_transition_time), str)
    ]


def written_generation(status: Mapping[str, Any]) -> int | None:
    """`status.observedGeneration` if it is a generation at all (others may write the field)."""
    value = status.get(keys.INSTANCE_STATUS.observed_generation)
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def merge_conditions(
    old: Iterable[dict[str, Any]],
    verdicts: Iterable[Verdict],
    *,
    generation: int | None,
    now: datetime,
) -> list[dict[str, Any]]:
    """The new condition list: one entry per verdict, in verdict order; old unknown types dropped.

    Args:
        old: the conditions currently in status (wire format).
        verdicts: the freshly computed values.
        generation: `metadata.generation` they were computed from.
        now: the clock, injected.

    Returns:
        Conditions in wire format (camelCase keys).
    """
    previous = {c.get(keys.CONDITION.type): c for c in old if isinstance(c, Mapping)}
    result: list[dict[str, Any]] = []
    for verdict in verdicts:
        before = previous.get(verdict.type.value)
        flipped = before is None or before.get(keys.CONDITION.status) != verdict.status_text
        entry = {
            keys.CONDITION.type: verdict.type.value,
            keys.CONDITION.status: verdict.status_text,
            keys.CONDITION.reason: verdict.reason.value,
            keys.CONDITION.message: _bounded(verdict.message),
            keys.CONDITION.last_transition_time: rfc3339(now)
            if flipped or not isinstance(before.get(keys.CONDITION.last_transition_time), str)
            else before[keys.CONDITION.last_transition_time],
        }
        if generation is not None:
            entry[keys.CONDITION.observed_generation] = generation
        result.append(entry)
    return result


def find(conditions: Iterable[dict[str, Any]], ctype: ConditionType) -> dict[str, Any] | None:
    """The condition of that type, if present."""
    for condition in conditions:
        if condition.get(keys.CONDITION.type) == ctype.value:
            return condition
    return None


def is_true(conditions: Iterable[dict[str, Any]], ctype: ConditionType) -> bool:
    """Whether the condition is present and True."""
    found = find(conditions, ctype)
    return bool(found and found.get(keys.CONDITION.status) == "True")
