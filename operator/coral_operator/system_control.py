"""Reading and merge-patching the CoralSystems of one namespace for the commands that steer them
(`halt_control`, `rollout_control`), with the user's own credentials."""

from __future__ import annotations

from typing import Any, Self

from coral_core import names
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_operator import user_client


class SystemControl:
    """The CoralSystems of one namespace; each command raises its own `error` for a missing system."""

    error: type[Exception] = LookupError

    def __init__(self, api_client: k8s.ApiClient, namespace: str) -> None:
        self.custom = k8s.CustomObjectsApi(api_client)
        self.namespace = namespace

    @classmethod
    def from_kubeconfig(cls, namespace: str) -> Self:
        return cls(user_client.user_api_client(), namespace)

    def read(self, system: str) -> dict[str, Any]:
        try:
            return self.custom.get_namespaced_custom_object(
                names.GROUP, names.VERSION, self.namespace, names.SYSTEM_PLURAL, system
            )
        except ApiException as error:
            if error.status == 404:
                raise self.error(f"coralsystem/{system} not found in namespace {self.namespace}") from error
            raise

    def patch(self, system: str, body: dict[str, Any]) -> None:
        """A merge patch: null removes a field, a list or object given replaces the old one whole."""
        self.custom.patch_namespaced_custom_object(
            names.GROUP,
            names.VERSION,
            self.namespace,
            names.SYSTEM_PLURAL,
            system,
            body,
            _content_type="application/merge-patch+json",
        )
