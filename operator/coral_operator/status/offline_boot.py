"""What a robot did with this instance's system when it last booted without the API server.

The robot's offline agent writes its boot report on its own Node once the link is back
(`coral.dev/offline-report`, docs/offline.md); this reads the part that concerns one instance into
the instance's `status.offlineBoot`, so the outcome is read where the robot's other state is. Pure;
called by `reconcile.instances`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from datetime import datetime
from typing import Any

from coral_core import offline

from coral_operator.api import OfflineBoot
from coral_operator.status.transitions import parse_rfc3339


def _report(annotations: Mapping[str, str]) -> dict[str, Any] | None:
    """The Node's report, if it is one: the robot writes it, so anything else is ignored."""
    try:
        report = json.loads(annotations.get(offline.ANNOTATION_NODE_REPORT) or "null")
    except ValueError:
        return None
    if not isinstance(report, dict) or not isinstance(report.get("systems"), dict):
        return None
    return report


def offline_boot(
    annotations: Mapping[str, str],
    *,
    namespace: str,
    system: str,
    offline_on: bool,
    created: datetime | None,
) -> dict[str, Any] | None:
    """The instance's `offlineBoot` (wire format), or None when there is nothing to tell.

    Told only for a system that lets its robots run offline, and only about a boot after the
    instance was made: an instance made later was never the robot's to run offline. A report that
    names no entry for the system means the robot had no revision of it stored.
    """
    report = _report(annotations)
    if not offline_on or report is None:
        return None
    booted_at = report.get("bootedAt")
    booted = _moment(booted_at)
    if booted_at is None or booted is None or created is None or created > booted:
        return None
    entry = report["systems"].get(offline.cache_name(namespace, system))
    if not isinstance(entry, dict):
        entry = {"action": offline.BootAction.NOTHING.value}
    try:
        outcome = offline.OUTCOMES[offline.BootAction(entry.get("action"))]
    except (KeyError, ValueError):
        return None  # an online boot, or an action this operator does not know
    # The run's summary is read only when it is shaped like one.
    run = entry.get("run") if isinstance(entry.get("run"), dict) else {}
    entry = entry | {"bootedAt": booted_at, "run": run}
    told = OfflineBoot(
        outcome=outcome,
        booted_at=booted_at,
        revision=_text(entry.get("revision")),
        handed_over_at=_text(entry.get("handedOverAt")),
        reason=_text(entry.get("reason")),
        message=offline.outcome_message(entry),
    )
    return told.model_dump(by_alias=True, exclude_none=True)


def _moment(value: Any) -> datetime | None:
    try:
        return parse_rfc3339(value) if isinstance(value, str) else None
    except ValueError:
        return None


def _text(value: Any) -> str | None:
    return value if isinstance(value, str) and value else None
