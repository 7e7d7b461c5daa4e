"""Revision history of a CoralSystem, kept as ControllerRevisions (as DaemonSets and StatefulSets do).

Every revision's template (what every robot of that revision runs, `planning.instances.build_template`)
is stored in a ControllerRevision owned by the system, so `coral rollout undo` and
`onFailure: Rollback` can return robots to a revision the spec no longer describes. Pure; the
system handler applies the plan through `kube.revisions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from coral_core import names
from coral_core.names import API_VERSION

from coral_operator.planning import naming

HISTORY_LIMIT = 10
"""Revisions kept per system, besides any a robot still runs."""
_ROBOT_FIELDS = ("system", "robot", "nodeName", "revision", "retiring", "halt")


@dataclass(frozen=True)
class StoredRevision:
    """One ControllerRevision as read back."""

    name: str
    revision: str
    """The revision hash."""
    number: int
    """Order of creation; re-applying an old revision gives it a new, highest number."""
    template: dict[str, Any]


@dataclass
class HistoryPlan:
    """What to do with the ControllerRevisions of one system."""

    create: dict[str, Any] | None = None
    """A ControllerRevision manifest for the newest revision, when it is not stored yet."""
    renumber: tuple[str, int] | None = None
    """(name, number) when an older stored revision became the newest again."""
    delete: list[str] = field(default_factory=list)
    order: list[str] = field(default_factory=list)
    """Revision hashes, oldest first, after the plan is applied."""


def revision_name(system: str, revision: str) -> str:
    return f"{naming.dns_label(system, 200)}-{revision}"


def template_of_instance(spec: dict[str, Any]) -> dict[str, Any]:
    """The template a CoralInstance's spec was built from (its spec without the robot's fields)."""
    return {key: value for key, value in spec.items() if key not in _ROBOT_FIELDS}


def build_revision(
    *, system: str, namespace: str, system_uid: str, revision: str, template: dict[str, Any], number: int
) -> dict[str, Any]:
    """The ControllerRevision manifest of one revision, owned by its CoralSystem."""
    return {
        "apiVersion": "apps/v1",
        "kind": "ControllerRevision",
        "metadata": {
            "name": revision_name(system, revision),
            "namespace": namespace,
            "labels": {
                names.LABEL_SYSTEM: naming.label_value(system),
                names.LABEL_REVISION: revision,
                names.LABEL_MANAGED_BY: names.MANAGER,
            },
            "ownerReferences": [naming.owner_reference(API_VERSION, names.SYSTEM_KIND, system, system_uid)],
        },
        "data": template,
        "revision": number,
    }


def plan_history(
    *,
    stored: list[StoredRevision],
    system: str,
    namespace: str,
    system_uid: str,
    revision: str,
    template: dict[str, Any],
    in_use: set[str],
    limit: int = HISTORY_LIMIT,
) -> HistoryPlan:
    """Store the newest revision, make it the highest-numbered, and prune the oldest beyond `limit`.

    Args:
        stored: the system's ControllerRevisions.
        revision: the spec's newest revision hash; `template` is what it runs.
        in_use: revisions some robot still runs; never pruned.
    """
    plan = HistoryPlan()
    numbers = {s.revision: s.number for s in stored}
    names = {s.revision: s.name for s in stored}
    top = max(numbers.values(), default=0)
    if revision not in numbers:
        numbers[revision] = top + 1
        names[revision] = revision_name(system, revision)
        plan.create = build_revision(
            system=system,
            namespace=namespace,
            system_uid=system_uid,
            revision=revision,
            template=template,
            number=top + 1,
        )
    elif numbers[revision] != top or list(numbers.values()).count(top) > 1:
        numbers[revision] = top + 1
        plan.renumber = (names[revision], top + 1)
    ordered = sorted(numbers, key=lambda r: numbers[r])
    excess = len(ordered) - limit
    for old in ordered[:-1]:
        if excess <= 0:
            break
        if old not in in_use:
            plan.delete.append(names[old])
            ordered.remove(old)
            excess -= 1
    plan.order = ordered
    return plan
