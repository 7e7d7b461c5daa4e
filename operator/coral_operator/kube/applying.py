"""Writes to the API: create-if-absent, patch-when-changed and delete, all idempotent.

A 409 on create means an earlier pass (or an operator before a restart) already made the object;
a 404 on delete means it is already gone. Called by the reconcilers (`reconcile/`) only.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any, TypeVar

from coral_core import names
from coral_core.names import GROUP, VERSION
from kubernetes.client.exceptions import ApiException

from coral_operator.kube import client

T = TypeVar("T")
R = TypeVar("R")

METADATA_ONLY = {"Accept": "application/json;as=PartialObjectMetadata;g=meta.k8s.io;v=v1"}
"""Asks the API server to answer a write with the object's metadata alone: a status write on a
megabyte CoralSystem would otherwise bring the whole megabyte back, to be read for its
resourceVersion."""


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
        # Nothing reads the answer: at fleet scale turning it into the client's models (or the
        # manifest into them on the way out) costs more CPU than the request.
        client.post(f"/api/v1/namespaces/{manifest['metadata']['namespace']}/pods", manifest)
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
            _headers=METADATA_ONLY,
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


class NameTaken(Exception):
    """An object a system needs exists under its name but is another owner's: not taken over, not
    deleted, reported (issue 47, item 9: a second system was silently never served, and deleting
    one deleted the other's ServiceAccount)."""

    def __init__(self, kind: str, namespace: str, name: str, owners: str) -> None:
        super().__init__(f"{kind} {name} already exists in namespace {namespace} and belongs to {owners}")


def _owners(references: Iterable[Any]) -> list[tuple[str, str, str]]:
    """(kind, name, uid) of owner references, read by the client as objects or as dicts."""
    found = []
    for reference in references:
        if isinstance(reference, dict):
            found.append((reference.get("kind", ""), reference.get("name", ""), reference.get("uid", "")))
        else:
            found.append((reference.kind, reference.name, reference.uid))
    return found


def _describe(owners: list[tuple[str, str, str]]) -> str:
    return ", ".join(f"{kind} {name}" for kind, name, _ in owners) or "no owner (made by hand)"


def _left_by_predecessor(owners: list[tuple[str, str, str]], manifest: dict[str, Any]) -> bool:
    """Whether every owner is an earlier CoralSystem of the same name (deleted, or deleted with
    orphaning): the only objects a system may take over."""
    mine = manifest["metadata"]["ownerReferences"][0]
    return all(kind == mine["kind"] and name == mine["name"] for kind, name, _ in owners)


def owned_by(owner_references: Iterable[Any] | None, uid: str) -> bool:
    """Whether one of `owner_references` (as the client reads them) names the owner `uid`."""
    return any(reference.uid == uid for reference in owner_references or [])


def _owner_uid(manifest: dict[str, Any]) -> str:
    return str(manifest["metadata"]["ownerReferences"][0]["uid"])


def _labels_match(current: Any, manifest: dict[str, Any]) -> bool:
    labels = current.metadata.labels or {}
    return all(labels.get(key) == value for key, value in manifest["metadata"]["labels"].items())


def create_owned(
    manifest: dict[str, Any],
    create: Callable[[str, dict[str, Any]], Any],
    read: Callable[[str, str], Any],
    take_over: Callable[[Any, dict[str, Any]], None],
) -> None:
    """Create an object owned by a system, or make the one already there the system's.

    A system deleted and created again under its name (`kubectl replace --force`, a GitOps tool
    recreating it) finds the first one's objects still there until the garbage collector reaches
    them: the same names, owned by the old uid. Taking the 409 as done would leave the new system
    relying on objects the collector is about to delete, and its later pods refused for want of
    their ServiceAccount. So an object with our labels whose owners are all earlier systems of the
    same name is handed to the new owner (the collector leaves an object alone once its owner
    exists), and one deleted between the 409 and the read is created again.

    Raises:
        NameTaken: the object belongs to anything else (another system, or no Coral system): it
            is not ours to take, and a system relying on it would run as someone else.
    """
    namespace, name = manifest["metadata"]["namespace"], manifest["metadata"]["name"]
    uid = _owner_uid(manifest)
    for _ in range(3):
        try:
            create(namespace, manifest)
            return
        except ApiException as error:
            _ignore(error, 409)
        try:
            current = read(name, namespace)
        except ApiException as error:
            _ignore(error, 404)
            continue
        if owned_by(current.metadata.owner_references, uid):
            return
        owners = _owners(current.metadata.owner_references or [])
        if not _labels_match(current, manifest) or not _left_by_predecessor(owners, manifest):
            raise NameTaken(manifest["kind"], namespace, name, _describe(owners))
        try:
            take_over(current, manifest)
            return
        except ApiException as error:
            _ignore(error, 404, 409)
    raise RuntimeError(f"{manifest['kind']} {namespace}/{name} kept changing while being created")


def _patch_owner(patch: Callable[..., Any]) -> Callable[[Any, dict[str, Any]], None]:
    def take_over(current: Any, manifest: dict[str, Any]) -> None:
        metadata = current.metadata
        # resourceVersion makes it a compare-and-swap: the collector may be deleting it right now.
        body = {
            "metadata": {
                "ownerReferences": manifest["metadata"]["ownerReferences"],
                "resourceVersion": metadata.resource_version,
            }
        }
        patch(metadata.name, metadata.namespace, body, _content_type="application/merge-patch+json")

    return take_over


def create_config_map(manifest: dict[str, Any]) -> None:
    """Create an immutable ConfigMap unless it exists (its name is its content hash)."""
    core = client.core()
    create_owned(
        manifest,
        core.create_namespaced_config_map,
        core.read_namespaced_config_map,
        _patch_owner(core.patch_namespaced_config_map),
    )


def delete_config_map(namespace: str, name: str) -> None:
    try:
        client.core().delete_namespaced_config_map(name, namespace)
    except ApiException as error:
        _ignore(error, 404)


def apply_rbac(objects: list[dict[str, Any]]) -> None:
    """Create the executors' ServiceAccount, Role and RoleBinding unless they exist."""
    core, rbac = client.core(), client.rbac()
    for manifest in objects:
        if manifest["kind"] == "ServiceAccount":
            calls = (
                core.create_namespaced_service_account,
                core.read_namespaced_service_account,
                core.patch_namespaced_service_account,
            )
        elif manifest["kind"] == "Role":
            calls = (rbac.create_namespaced_role, rbac.read_namespaced_role, rbac.patch_namespaced_role)
        else:
            calls = (
                rbac.create_namespaced_role_binding,
                rbac.read_namespaced_role_binding,
                rbac.patch_namespaced_role_binding,
            )
        create, read, patch = calls
        create_owned(manifest, create, read, _patch_owner(patch))


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


def create_instance(manifest: dict[str, Any]) -> dict[str, Any] | None:
    """Create an instance; returns it as created, or None when it already existed for this system
    (or an earlier one of its name, whose instances the collector is removing).

    Raises:
        NameTaken: an instance of that name belongs to anything else.
    """
    namespace, name = manifest["metadata"]["namespace"], manifest["metadata"]["name"]
    custom = client.custom()
    try:
        created: dict[str, Any] = custom.create_namespaced_custom_object(
            GROUP, VERSION, namespace, "coralinstances", manifest
        )
    except ApiException as error:
        _ignore(error, 409)
    else:
        return created
    try:
        current = custom.get_namespaced_custom_object(GROUP, VERSION, namespace, "coralinstances", name)
    except ApiException as error:
        _ignore(error, 404)
        return None  # gone since: the next pass creates it
    owners = _owners(current.get("metadata", {}).get("ownerReferences") or [])
    if not _left_by_predecessor(owners, manifest) or not owners:
        raise NameTaken(manifest["kind"], namespace, name, _describe(owners))
    return None


def update_instance(manifest: dict[str, Any]) -> dict[str, Any] | None:
    """Replace an instance's spec, labels and owner (a JSON merge patch would keep removed list
    items); returns it as updated, or None when it is gone. The owner makes an instance written by
    hand at the system's name the system's (`planning.provenance`)."""
    body = [
        {"op": "replace", "path": "/spec", "value": manifest["spec"]},
        {"op": "add", "path": "/metadata/labels", "value": manifest["metadata"]["labels"]},
        {"op": "add", "path": "/metadata/ownerReferences", "value": manifest["metadata"]["ownerReferences"]},
    ]
    try:
        updated: dict[str, Any] = client.custom().patch_namespaced_custom_object(
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
        return None
    return updated


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


@dataclass(frozen=True)
class SourceKey:
    """One key of a ConfigMap a system names, with the labels its owners gave the ConfigMap."""

    text: str | None
    """None when the key is missing."""
    labels: dict[str, str]


def read_config_map_key(namespace: str, name: str, key: str) -> SourceKey | None:
    """The text under `key` and the ConfigMap's labels; None when the ConfigMap is missing. Another
    4xx raises, for `refusal` to turn into a status."""
    try:
        config_map = client.core().read_namespaced_config_map(name, namespace)
    except ApiException as error:
        _ignore(error, 404)
        return None
    return SourceKey(text=(config_map.data or {}).get(key), labels=dict(config_map.metadata.labels or {}))


def read_system(namespace: str, name: str) -> dict[str, Any] | None:
    """The CoralSystem as the API server holds it now, or None when it is gone."""
    try:
        body: dict[str, Any] = client.custom().get_namespaced_custom_object(
            GROUP, VERSION, namespace, names.SYSTEM_PLURAL, name
        )
    except ApiException as error:
        _ignore(error, 404)
        return None
    return body
