"""An in-memory `kube.writer.Writer` for the reconcilers' unit tests.

It keeps what a pass wrote, in order, answers as the API server would (a resourceVersion per
status patch, the object as created or updated), and can refuse a write as an admission controller
would. A refusal is the 403 and message the API server would send: that fault cannot be caused
without a cluster.
"""

from __future__ import annotations

import json
from datetime import datetime, timedelta
from typing import Any

from coral_core import names
from coral_operator.kube import applying
from coral_operator.planning.revisions import StoredRevision
from kubernetes.client.exceptions import ApiException
from operator_specs import NOW


class FakeWriter:
    """What the reconcilers wrote (`writes`, as (verb, name)) and the objects as it holds them."""

    def __init__(self) -> None:
        self.writes: list[tuple[str, str]] = []
        self.pods: dict[str, dict[str, Any]] = {}
        self.instances: dict[str, dict[str, Any]] = {}
        self.status: dict[str, dict[str, Any]] = {}
        self.config_maps: dict[str, dict[str, str]] = {}
        self.config_map_labels: dict[str, dict[str, str]] = {}
        """Labels of `config_maps` by name; unset, a ConfigMap is marked as a Coral source."""
        self.refuse_config_maps: tuple[int, str] | None = None
        self.revisions: list[StoredRevision] = []
        self.refuse_pods = ""
        self.refuse_instances = ""
        self.taken_by = ""
        """Set: every instance name is another owner's (`applying.NameTaken` naming it)."""
        self.renewed = NOW - timedelta(minutes=3)
        self.systems: dict[str, dict[str, Any]] = {}
        """CoralSystems as `read_system` answers, by name."""
        self.version = 100
        """The resourceVersion of the last write, as a number (the API server's are opaque strings)."""

    def of(self, verb: str) -> list[str]:
        """Names written with `verb`; a pod by its instance and component (its suffix is a hash)."""
        written = [name for done, name in self.writes if done == verb]
        return [name.rsplit("-", 1)[0] for name in written] if verb.endswith("pod") else written

    @staticmethod
    def _refused(message: str, status: int = 403, reason: str = "Forbidden") -> ApiException:
        error = ApiException(status=status, reason=reason)
        error.body = json.dumps({"message": message})
        return error

    # --- pods ----------------------------------------------------------------------------------

    def create_pod(self, manifest: dict[str, Any]) -> bool:
        if self.refuse_pods:
            raise self._refused(self.refuse_pods)
        self.writes.append(("create pod", manifest["metadata"]["name"]))
        self.pods[manifest["metadata"]["name"]] = manifest
        return True

    def delete_pod(self, namespace: str, name: str) -> None:
        self.writes.append(("delete pod", name))
        self.pods.pop(name, None)

    def delete_pods(self, namespace: str, labels: dict[str, str]) -> None:
        for name, manifest in list(self.pods.items()):
            if labels.items() <= manifest["metadata"]["labels"].items():
                self.delete_pod(namespace, name)

    def patch_pod_labels(self, namespace: str, name: str, labels: dict[str, str]) -> None:
        self.writes.append(("relabel pod", name))

    def patch_pod(self, namespace: str, name: str, patch: dict[str, Any]) -> None:
        self.writes.append(("patch pod", name))

    # --- statuses ------------------------------------------------------------------------------

    def patch_instance_status(self, namespace: str, name: str, changes: dict[str, Any]) -> str:
        return self._patch_status(name, changes)

    def patch_system_status(self, namespace: str, name: str, changes: dict[str, Any]) -> str:
        return self._patch_status(name, changes)

    def _patch_status(self, name: str, changes: dict[str, Any]) -> str:
        """A JSON merge patch, one level deep as the reconcilers send it."""
        self.writes.append(("patch status", name))
        merged = self.status.setdefault(name, {})
        for key, value in changes.items():
            if isinstance(value, dict) and isinstance(merged.get(key), dict):
                merged[key] = {k: v for k, v in {**merged[key], **value}.items() if v is not None}
            elif value is None:
                merged.pop(key, None)
            else:
                merged[key] = value
        self.version += 1
        return str(self.version)

    # --- instances -----------------------------------------------------------------------------

    def _write_instance(self, verb: str, manifest: dict[str, Any], generation: int) -> dict[str, Any]:
        """Stores the instance and answers as the API server would."""
        name = manifest["metadata"]["name"]
        self.writes.append((verb, name))
        self.instances[name] = manifest
        self.version += 1
        metadata = {**manifest["metadata"], "uid": "uid-" + name, "resourceVersion": str(self.version)}
        return {**manifest, "metadata": {**metadata, "generation": generation}}

    def create_instance(self, manifest: dict[str, Any]) -> dict[str, Any]:
        if self.refuse_instances:
            raise self._refused(self.refuse_instances)
        if self.taken_by:
            metadata = manifest["metadata"]
            raise applying.NameTaken("CoralInstance", metadata["namespace"], metadata["name"], self.taken_by)
        return self._write_instance("create instance", manifest, 1)

    def update_instance(self, manifest: dict[str, Any]) -> dict[str, Any]:
        return self._write_instance("update instance", manifest, 2)

    def retire_instance(self, namespace: str, name: str) -> None:
        self.writes.append(("retire instance", name))

    def delete_instance(self, namespace: str, name: str) -> None:
        self.writes.append(("delete instance", name))

    # --- what a system writes besides its instances -----------------------------------------

    def apply_rbac(self, objects: list[dict[str, Any]]) -> None:
        self.writes.append(("apply rbac", objects[0]["metadata"]["name"]))

    def create_config_map(self, manifest: dict[str, Any]) -> None:
        self.writes.append(("create configmap", manifest["metadata"]["name"]))

    def delete_config_map(self, namespace: str, name: str) -> None:
        self.writes.append(("delete configmap", name))

    def read_config_map_key(self, namespace: str, name: str, key: str) -> applying.SourceKey | None:
        if self.refuse_config_maps is not None:
            code, message = self.refuse_config_maps
            raise self._refused(message, code, "Refused")
        if name not in self.config_maps:
            return None
        labels = self.config_map_labels.get(name, {names.LABEL_SOURCE: "true"})
        return applying.SourceKey(text=self.config_maps[name].get(key), labels=labels)

    def read_system(self, namespace: str, name: str) -> dict[str, Any] | None:
        return self.systems.get(name)

    def read_renew_time(self, node_name: str) -> datetime | None:
        return self.renewed

    # --- revisions -----------------------------------------------------------------------------

    def read_revisions(self, namespace: str, system: str, uid: str) -> list[StoredRevision]:
        return list(self.revisions)

    def create_revision(self, manifest: dict[str, Any]) -> None:
        self.writes.append(("create revision", ""))

    def renumber_revision(self, namespace: str, name: str, number: int) -> None:
        self.writes.append(("renumber revision", str(number)))

    def delete_revision(self, namespace: str, name: str) -> None:
        self.writes.append(("delete revision", name))
