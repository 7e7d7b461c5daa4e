"""Reads and writes the ControllerRevisions holding a CoralSystem's revision history.

Planned by `planning.revisions`; called by the system reconciler (`reconcile.systems`), whose
`Memory` keeps what it read, so the API is listed once per system per operator process.
"""

from __future__ import annotations

from typing import Any

from coral_core import names
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_operator.kube import client
from coral_operator.kube.applying import create_owned, owned_by
from coral_operator.planning import naming
from coral_operator.planning.revisions import StoredRevision


def _apps() -> k8s.AppsV1Api:
    return k8s.AppsV1Api(client.api_client())


def read_revisions(namespace: str, system: str, uid: str) -> list[StoredRevision]:
    """The history of the system with owner `uid`; an earlier system of that name left its own for
    the garbage collector, and it is not this one's to roll back to."""
    selector = (
        f"{names.LABEL_SYSTEM}={naming.label_value(system)},{names.LABEL_MANAGED_BY}={names.MANAGER}"
    )
    items = _apps().list_namespaced_controller_revision(namespace, label_selector=selector).items
    return [
        StoredRevision(
            name=item.metadata.name,
            revision=(item.metadata.labels or {}).get(names.LABEL_REVISION, ""),
            number=int(item.revision or 0),
            template=dict(item.data or {}),
        )
        for item in items
        if (item.metadata.labels or {}).get(names.LABEL_REVISION)
        and owned_by(item.metadata.owner_references, uid)
    ]


def create_revision(manifest: dict[str, Any]) -> None:
    """Create a revision, or take over the one an earlier system of the same name left behind."""
    apps = _apps()
    create_owned(
        manifest,
        apps.create_namespaced_controller_revision,
        apps.read_namespaced_controller_revision,
        _take_over,
    )


def _take_over(current: k8s.V1ControllerRevision, manifest: dict[str, Any]) -> None:
    """Give a revision its new owner and number, `data` left as stored (see `renumber_revision`)."""
    apps = _apps()
    current.metadata.owner_references = manifest["metadata"]["ownerReferences"]
    current.revision = manifest["revision"]
    try:
        metadata = current.metadata
        apps.replace_namespaced_controller_revision(metadata.name, metadata.namespace, current)
    except ApiException as error:
        if error.status != 422:
            raise
        _recreate(apps, current)


def renumber_revision(namespace: str, name: str, number: int) -> None:
    """Give a stored revision a new number, leaving its `data` byte for byte as stored.

    `data` is immutable, and the apiserver compares it byte for byte: a patch makes the server
    re-encode it (compactly) and is refused with 422, which wedged every revert. So the object is
    read and put back whole with only `revision` changed, as client-go's UpdateControllerRevision
    does; this client re-encodes `data` exactly as it wrote it. A revision stored in another
    encoding (written by another client) is recreated instead: same name, same template.
    """
    apps = _apps()
    for _ in range(5):
        try:
            current = apps.read_namespaced_controller_revision(name, namespace)
        except ApiException as error:
            if error.status == 404:
                return
            raise
        if current.revision == number:
            return
        current.revision = number
        try:
            apps.replace_namespaced_controller_revision(name, namespace, current)
            return
        except ApiException as error:
            if error.status == 409:
                continue
            if error.status == 404:
                return
            if error.status != 422:
                raise
        _recreate(apps, current)
        return
    raise RuntimeError(f"ControllerRevision {namespace}/{name} kept changing while being renumbered")


def _recreate(apps: k8s.AppsV1Api, current: k8s.V1ControllerRevision) -> None:
    metadata = current.metadata
    apps.delete_namespaced_controller_revision(
        metadata.name,
        metadata.namespace,
        body=k8s.V1DeleteOptions(preconditions=k8s.V1Preconditions(uid=metadata.uid)),
    )
    create_revision(
        {
            "apiVersion": "apps/v1",
            "kind": "ControllerRevision",
            "metadata": {
                "name": metadata.name,
                "namespace": metadata.namespace,
                "labels": metadata.labels,
                "ownerReferences": [
                    client.api_client().sanitize_for_serialization(ref)
                    for ref in metadata.owner_references or []
                ],
            },
            "data": current.data,
            "revision": current.revision,
        }
    )


def delete_revision(namespace: str, name: str) -> None:
    try:
        _apps().delete_namespaced_controller_revision(name, namespace)
    except ApiException as error:
        if error.status != 404:
            raise
