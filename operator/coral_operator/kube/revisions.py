"""Reads and writes the ControllerRevisions holding a CoralSystem's revision history.

Planned by `planning.revisions`; called by the rollout glue in `handlers.rollouts`, which caches
what it read, so the API is listed once per system per operator process.
"""

from __future__ import annotations

from typing import Any

from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_operator.kube import client
from coral_operator.planning import naming
from coral_operator.planning.revisions import StoredRevision


def _apps() -> k8s.AppsV1Api:
    return k8s.AppsV1Api(client.api_client())


def read_revisions(namespace: str, system: str) -> list[StoredRevision]:
    selector = (
        f"{naming.LABEL_SYSTEM}={naming.label_value(system)},{naming.LABEL_MANAGED_BY}={naming.MANAGER}"
    )
    items = _apps().list_namespaced_controller_revision(namespace, label_selector=selector).items
    return [
        StoredRevision(
            name=item.metadata.name,
            revision=(item.metadata.labels or {}).get(naming.LABEL_REVISION, ""),
            number=int(item.revision or 0),
            template=dict(item.data or {}),
        )
        for item in items
        if (item.metadata.labels or {}).get(naming.LABEL_REVISION)
    ]


def create_revision(manifest: dict[str, Any]) -> None:
    try:
        _apps().create_namespaced_controller_revision(manifest["metadata"]["namespace"], manifest)
    except ApiException as error:
        if error.status != 409:
            raise


def renumber_revision(namespace: str, name: str, number: int) -> None:
    try:
        _apps().patch_namespaced_controller_revision(name, namespace, {"revision": number})
    except ApiException as error:
        if error.status != 404:
            raise


def delete_revision(namespace: str, name: str) -> None:
    try:
        _apps().delete_namespaced_controller_revision(name, namespace)
    except ApiException as error:
        if error.status != 404:
            raise
