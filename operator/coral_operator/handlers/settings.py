"""Operator-wide kopf settings, applied at startup.

Progress and diff-base go to `coral.dev/` annotations (status belongs to the CRD schema, which
would prune kopf's own fields); no finalizers, so a stopped operator never blocks a deletion.
"""

from __future__ import annotations

import logging
from typing import Any

import kopf

from coral_operator.kube import applying


@kopf.on.startup()
def configure_operator(settings: kopf.OperatorSettings, **_: Any) -> None:
    settings.persistence.progress_storage = kopf.AnnotationsProgressStorage(prefix="coral.dev")
    settings.persistence.diffbase_storage = kopf.AnnotationsDiffBaseStorage(
        prefix="coral.dev", key="last-handled-configuration"
    )
    # Only warnings become Kubernetes Events automatically; the handlers post their own.
    settings.posting.level = logging.WARNING
    settings.execution.max_workers = 16
    settings.watching.server_timeout = 300
    settings.networking.request_timeout = 60


@kopf.on.startup()
def wait_for_the_coral_api(settings: kopf.OperatorSettings, memo: kopf.Memo, **_: Any) -> None:
    # Watching a CRD whose storage is still initializing can leave an index unfilled for good,
    # which holds every handler back; start watching only once both kinds are served.
    problem = applying.coral_api_served(list(memo.get("namespaces", [])))
    if problem is not None:
        raise kopf.TemporaryError(f"Waiting for the coral.dev API: {problem}", delay=1)
