"""Writes to the API: create-if-absent, patch-when-changed and delete, all idempotent.

A 409 on create means an earlier pass (or an operator before a restart) already made the object;
a 404 on delete means it is already gone. Called by the reconcilers (`reconcile/`) only.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from concurrent.futures import Executor
from typing import Any, TypeVar

from kubernetes.client.exceptions import ApiException

from coral_operator.api import names
from coral_operator.api.names import GROUP, VERSION
from coral_operator.kube import client
from coral_operator.planning import naming

T = TypeVar("T")
R = TypeVar("R")


def in_parallel(pool: Executor, call: Callable[[T], R], items: Iterable[T]) -> list[R]:
    """`call` on every item, a few at a time on `pool`; results in item order; the first error is
    raised. API calls wait on the network, so a fleet's worth of them overlap instead of queueing."""
    return list(pool.map(call, list(items)))


def _ignore(error: ApiException, *codes: int) -> None:
    if error.status not in codes:
        raise error


def is_api_error(error: BaseException) -> bool:
    return isinstance(error, ApiException)


def refusal(error: BaseException) -> str | None:
    """The API server's message when it refused a write for good (validation, admission, quota,
    Pod Security, forbidden); None for errors worth retrying (conflicts, throttling, outages)."""
    if not isinstance(error, ApiException) or error.status is None:
        return None
    if not 400 <= error.status < 500 or error.status in (404, 408, 409, 429):
        return None
    try:
        message = json.loads(error.body or "{}").get("message")
    except (ValueError, AttributeError):
        message = None
    return str(message or error.reason or f"HTTP {error.status}")


def _drain(response: Any) -> int:
    """Read an answer left raw, so its connection goes back to the pool; returns its size."""
    return len(response.data)


def create_pod(manifest: dict[str, Any]) -> bool:
    """Create a pod; False when it already existed."""
    try:
        # The answer is left raw: nothing reads it, and at fleet scale turning it into the
        # client's model objects costs more CPU than the request.
        _drain(
            client.core().create_namespaced_pod(
                manifest["metadata"]["namespace"], manifest, _preload_content=False
            )
        )
    except ApiException as error:
        _ignore(error, 409)
        return False
    return True


def delete_pod(namespace: str, name: str) -> None:
    try:
        _drain(client.core().delete_namespaced_pod(name, namespace, _preload_content=False))
    except ApiException as error:
        _ignore(error, 404)


def delete_pods(namespace: str, labels: dict[str, str]) -> None:
    """Delete every pod carrying `labels` in one request (none left is success)."""
    selector = ",".join(f"{key}={value}" for key, value in sorted(labels.items()))
    # No resourceVersion: on a collection delete it is a precondition on every pod, not a cache hint.
    _drain(
        client.core().delete_collection_namespaced_pod(
            namespace, label_selector=selector, _preload_content=False
        )
    )


def patch_pod_labels(namespace: str, name: str, labels: dict[str, str]) -> None:
    try:
        client.core().patch_namespaced_pod(
            name, namespace, {"metadata": {"labels": labels}}, _content_type="application/merge-patch+json"
        )
    except ApiException as error:
        _ignore(error, 404)


def patch_pod(namespace: str, name: str, patch: dict[str, Any]) -> None:
    """A strategic merge patch: container lists merge by name, so only the named images change."""
    try:
        client.core().patch_namespaced_pod(
            name, namespace, patch, _content_type="application/strategic-merge-patch+json"
        )
    except ApiException as error:
        _ignore(error, 404)


def patch_instance_status(namespace: str, name: str, changes: dict[str, Any]) -> str | None:
    """Merge `changes` into an instance's status; the resourceVersion it made, None when the
    instance is gone."""
    return _patch_status("coralinstances", namespace, name, changes)


def patch_system_status(namespace: str, name: str, changes: dict[str, Any]) -> str | None:
    """Merge `changes` into a system's status; the resourceVersion it made, None when it is gone."""
    return _patch_status("coralsystems", namespace, name, changes)


def _patch_status(plural: str, namespace: str, name: str, changes: dict[str, Any]) -> str | None:
    try:
        response = client.custom().patch_namespaced_custom_object_status(
            GROUP,
            VERSION,
            namespace,
            plural,
            name,
            {"status": changes},
            _content_type="application/merge-patch+json",
            _preload_content=False,
        )
    except ApiException as error:
        _ignore(error, 404)
        return None
    try:
        version = json.loads(response.data)["metadata"]["resourceVersion"]
    except (ValueError, KeyError, TypeError):
        return ""
    return str(version)


def create_config_map(manifest: dict[str, Any]) -> None:
    """Create an immutable ConfigMap unless it exists (its name is its content hash)."""
    try:
        client.core().create_namespaced_config_map(manifest["metadata"]["namespace"], manifest)
    except ApiException as error:
        _ignore(error, 409)


def delete_config_map(namespace: str, name: str) -> None:
    try:
        client.core().delete_namespaced_config_map(name, namespace)
    except ApiException as error:
        _ignore(error, 404)


def apply_rbac(objects: list[dict[str, Any]]) -> None:
    """Create the executors' ServiceAccount, Role and RoleBinding unless they exist."""
    for manifest in objects:
        namespace = manifest["metadata"]["namespace"]
        try:
            if manifest["kind"] == "ServiceAccount":
                client.core().create_namespaced_service_account(namespace, manifest)
            elif manifest["kind"] == "Role":
                client.rbac().create_namespaced_role(namespace, manifest)
            else:
                client.rbac().create_namespaced_role_binding(namespace, manifest)
        except ApiException as error:
            _ignore(error, 409)


def ensure_admission_policy(objects: list[dict[str, Any]], hash_annotation: str) -> list[str]:
    """Bring a ValidatingAdmissionPolicy and its binding to `objects`; returns the names applied.

    One read each; a server-side apply only where the object is missing or its `hash_annotation`
    differs (an older operator's, or none): a Helm install renders them already, and a namespaced
    install may read them but not write them.
    """
    api = client.admission()
    applied = []
    for manifest in objects:
        policy = manifest["kind"] == "ValidatingAdmissionPolicy"
        name = manifest["metadata"]["name"]
        read = (
            api.read_validating_admission_policy if policy else api.read_validating_admission_policy_binding
        )
        try:
            current = (read(name).metadata.annotations or {}).get(hash_annotation)
        except ApiException as error:
            _ignore(error, 404)
            current = None
        if current == manifest["metadata"]["annotations"][hash_annotation]:
            continue
        apply = (
            api.patch_validating_admission_policy if policy else api.patch_validating_admission_policy_binding
        )
        _drain(
            apply(
                name,
                manifest,
                field_manager=names.MANAGER,
                force=True,
                _content_type="application/apply-patch+yaml",
                _preload_content=False,
            )
        )
        applied.append(name)
    return applied


def create_instance(manifest: dict[str, Any]) -> bool:
    try:
        client.custom().create_namespaced_custom_object(
            GROUP, VERSION, manifest["metadata"]["namespace"], "coralinstances", manifest
        )
    except ApiException as error:
        _ignore(error, 409)
        return False
    return True


def update_instance(manifest: dict[str, Any]) -> None:
    """Replace an instance's spec and labels (a JSON merge patch would keep removed list items)."""
    body = [
        {"op": "replace", "path": "/spec", "value": manifest["spec"]},
        {"op": "replace", "path": "/metadata/labels", "value": manifest["metadata"]["labels"]},
    ]
    try:
        client.custom().patch_namespaced_custom_object(
            GROUP,
            VERSION,
            manifest["metadata"]["namespace"],
            "coralinstances",
            manifest["metadata"]["name"],
            body,
            _content_type="application/json-patch+json",
        )
    except ApiException as error:
        _ignore(error, 404)


def retire_instance(namespace: str, name: str) -> None:
    """Ask an instance to stop its components in reverse order and then remove itself."""
    try:
        client.custom().patch_namespaced_custom_object(
            GROUP,
            VERSION,
            namespace,
            "coralinstances",
            name,
            {"spec": {"retiring": True}},
            _content_type="application/merge-patch+json",
        )
    except ApiException as error:
        _ignore(error, 404)


def delete_instance(namespace: str, name: str) -> None:
    try:
        client.custom().delete_namespaced_custom_object(GROUP, VERSION, namespace, "coralinstances", name)
    except ApiException as error:
        _ignore(error, 404)


def coral_api_served(namespaces: list[str]) -> str | None:
    """None when both kinds can be listed where the operator serves, else what is not served yet.

    A CRD created a moment ago answers 404 or 429 ("storage is (re)initializing") for a while.
    """
    api = client.custom()
    for plural in ("coralsystems", "coralinstances"):
        for namespace in namespaces or [None]:
            try:
                if namespace is None:
                    api.list_cluster_custom_object(GROUP, VERSION, plural, limit=1)
                else:
                    api.list_namespaced_custom_object(GROUP, VERSION, namespace, plural, limit=1)
            except ApiException as error:
                if error.status in (404, 429, 503):
                    return f"{plural}.{GROUP} answers {error.status} ({error.reason})"
                raise
    return None


def read_config_map_key(namespace: str, name: str, key: str) -> str | None:
    """The text under `key`, or None when the ConfigMap or the key is missing."""
    try:
        config_map = client.core().read_namespaced_config_map(name, namespace)
    except ApiException as error:
        _ignore(error, 404)
        return None
    return (config_map.data or {}).get(key)


def list_system_config_maps(namespace: str, system: str) -> list[str]:
    """Names of the revision ConfigMaps the operator made for one system."""
    selector = (
        f"{names.LABEL_SYSTEM}={naming.label_value(system)},{names.LABEL_MANAGED_BY}={names.MANAGER}"
    )
    items = client.core().list_namespaced_config_map(namespace, label_selector=selector).items
    return [item.metadata.name for item in items]
