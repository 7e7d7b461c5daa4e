"""The API calls a reconcile pass makes, as one interface the reconcilers are given.

A pass writes pods, CoralInstances, ConfigMaps, RBAC, revisions and statuses, and reads the few
things its indexes do not hold (a Node's Lease, a system's large files, a source ConfigMap, the
revision history once). `Writer` names exactly those calls; `KubeWriter` makes them against the
API server (`kube.applying`, `kube.revisions`, `kube.leases`). Unit tests hand the reconcilers an
in-memory writer instead, so they run a pass as the operator runs it, without a cluster.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Protocol

from coral_operator.kube import applying, leases, revisions
from coral_operator.kube.applying import SourceKey
from coral_operator.planning.revisions import StoredRevision


class Writer(Protocol):
    """What a reconcile pass asks of the API server; each call is idempotent (`kube.applying`)."""

    def create_pod(self, manifest: dict[str, Any]) -> bool: ...

    def delete_pod(self, namespace: str, name: str) -> None: ...

    def delete_pods(self, namespace: str, labels: dict[str, str]) -> None: ...

    def patch_pod_labels(self, namespace: str, name: str, labels: dict[str, str]) -> None: ...

    def patch_pod(self, namespace: str, name: str, patch: dict[str, Any]) -> None: ...

    def patch_instance_status(self, namespace: str, name: str, changes: dict[str, Any]) -> str | None: ...

    def patch_system_status(self, namespace: str, name: str, changes: dict[str, Any]) -> str | None: ...

    def create_instance(self, manifest: dict[str, Any]) -> dict[str, Any] | None: ...

    def update_instance(self, manifest: dict[str, Any]) -> dict[str, Any] | None: ...

    def retire_instance(self, namespace: str, name: str) -> None: ...

    def delete_instance(self, namespace: str, name: str) -> None: ...

    def apply_rbac(self, objects: list[dict[str, Any]]) -> None: ...

    def create_config_map(self, manifest: dict[str, Any]) -> None: ...

    def delete_config_map(self, namespace: str, name: str) -> None: ...

    def read_config_map_key(self, namespace: str, name: str, key: str) -> SourceKey | None: ...

    def read_system(self, namespace: str, name: str) -> dict[str, Any] | None: ...

    def read_renew_time(self, node_name: str) -> datetime | None: ...

    def read_revisions(self, namespace: str, system: str, uid: str) -> list[StoredRevision]: ...

    def create_revision(self, manifest: dict[str, Any]) -> None: ...

    def renumber_revision(self, namespace: str, name: str, number: int) -> None: ...

    def delete_revision(self, namespace: str, name: str) -> None: ...


class KubeWriter:
    """`Writer` against the API server of the process's client (`kube.client`)."""

    create_pod = staticmethod(applying.create_pod)
    delete_pod = staticmethod(applying.delete_pod)
    delete_pods = staticmethod(applying.delete_pods)
    patch_pod_labels = staticmethod(applying.patch_pod_labels)
    patch_pod = staticmethod(applying.patch_pod)
    patch_instance_status = staticmethod(applying.patch_instance_status)
    patch_system_status = staticmethod(applying.patch_system_status)
    create_instance = staticmethod(applying.create_instance)
    update_instance = staticmethod(applying.update_instance)
    retire_instance = staticmethod(applying.retire_instance)
    delete_instance = staticmethod(applying.delete_instance)
    apply_rbac = staticmethod(applying.apply_rbac)
    create_config_map = staticmethod(applying.create_config_map)
    delete_config_map = staticmethod(applying.delete_config_map)
    read_config_map_key = staticmethod(applying.read_config_map_key)
    read_system = staticmethod(applying.read_system)
    read_renew_time = staticmethod(leases.read_renew_time)
    read_revisions = staticmethod(revisions.read_revisions)
    create_revision = staticmethod(revisions.create_revision)
    renumber_revision = staticmethod(revisions.renumber_revision)
    delete_revision = staticmethod(revisions.delete_revision)
