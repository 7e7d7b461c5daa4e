"""Small readers and writers of coral.dev objects and pods for the operator's integration tests.

`client_with_token` and `denied` live in fixtures.apiclients, `condition` and `is_current_and_true` in
fixtures.conditions (the kind tests use them too).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml
from coral_core import names
from coral_core.names import GROUP, VERSION
from coral_operator.planning.naming import EXECUTOR_ACCOUNT_PREFIX
from fixtures.apiclients import client_with_token
from fixtures.apiclients import denied as denied  # re-exported: the operator tests read it from here
from fixtures.conditions import condition as condition  # re-exported, as `denied`
from fixtures.conditions import is_current_and_true as is_current_and_true
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

ROOT = Path(__file__).resolve().parents[3]


def fleet_mission(name: str, fleet: str) -> dict[str, Any]:
    """The fleet example, renamed and selecting only this test's robots."""
    manifest = yaml.safe_load((ROOT / "examples" / "fleet" / "mission.yaml").read_text())
    manifest = copy.deepcopy(manifest)
    manifest["metadata"]["name"] = name
    manifest["spec"]["robots"] = {"matchLabels": {"fleet": fleet}}
    return manifest


def client_as(cluster: Any, namespace: str, account: str, pod: k8s.V1Pod | None = None) -> k8s.ApiClient:
    """An API client authenticated as a ServiceAccount; with `pod`, by a token bound to that pod, as
    the kubelet projects one (the API server then names the pod's Node in the user's extra fields)."""
    bound = (
        [
            "--bound-object-kind=Pod",
            f"--bound-object-name={pod.metadata.name}",
            f"--bound-object-uid={pod.metadata.uid}",
        ]
        if pod is not None
        else []
    )
    token = cluster.kubectl(
        "create", "token", account, "-n", namespace, "--duration=10m", *bound
    ).stdout.strip()
    return client_with_token(cluster, token)


def executor_pod(cluster: Any, namespace: str, instance: str) -> k8s.V1Pod:
    """The pod running the executor of one CoralInstance (either layout)."""
    pods = (
        k8s.CoreV1Api(cluster.api_client)
        .list_namespaced_pod(namespace, label_selector=f"{names.LABEL_INSTANCE}={instance}")
        .items
    )
    return next(p for p in pods if (p.spec.service_account_name or "").startswith(EXECUTOR_ACCOUNT_PREFIX))


def executor_client(cluster: Any, namespace: str, instance: str) -> k8s.ApiClient:
    """An API client holding the identity of one instance's executor, bound to its pod."""
    pod = executor_pod(cluster, namespace, instance)
    return client_as(cluster, namespace, pod.spec.service_account_name, pod)


class Coral:
    """Typed-enough access to one namespace."""

    def __init__(self, api_client: k8s.ApiClient, namespace: str) -> None:
        self.custom = k8s.CustomObjectsApi(api_client)
        self.core = k8s.CoreV1Api(api_client)
        self.namespace = namespace

    def create_system(self, manifest: dict[str, Any]) -> dict[str, Any]:
        return self.custom.create_namespaced_custom_object(
            GROUP, VERSION, self.namespace, "coralsystems", manifest
        )

    def patch_system(self, name: str, patch: Any, content_type: str = "application/merge-patch+json") -> None:
        self.custom.patch_namespaced_custom_object(
            GROUP, VERSION, self.namespace, "coralsystems", name, patch, _content_type=content_type
        )

    def delete_system(self, name: str) -> None:
        self.custom.delete_namespaced_custom_object(GROUP, VERSION, self.namespace, "coralsystems", name)

    def system(self, name: str) -> dict[str, Any] | None:
        try:
            return self.custom.get_namespaced_custom_object(
                GROUP, VERSION, self.namespace, "coralsystems", name
            )
        except ApiException as error:
            if error.status == 404:
                return None
            raise

    def served(self, name: str) -> bool:
        """Whether the operator wrote the system's first status for its current spec."""
        system = self.system(name)
        return (
            bool(system)
            and (system.get("status") or {}).get("observedGeneration") == system["metadata"]["generation"]
        )

    def instances(self) -> dict[str, dict[str, Any]]:
        items = self.custom.list_namespaced_custom_object(GROUP, VERSION, self.namespace, "coralinstances")[
            "items"
        ]
        return {item["metadata"]["name"]: item for item in items}

    def pods(self) -> dict[str, Any]:
        return {p.metadata.name: p for p in self.core.list_namespaced_pod(self.namespace).items}

    def config_maps(self) -> list[str]:
        items = self.core.list_namespaced_config_map(self.namespace, label_selector="coral.dev/system").items
        return [c.metadata.name for c in items]


def pod_ready_since(pod: Any) -> Any:
    for entry in pod.status.conditions or []:
        if entry.type == "Ready" and entry.status == "True":
            return entry.last_transition_time
    return None
