"""The shared Kubernetes API client of the operator process (in-cluster or from KUBECONFIG).

Used by `kube.applying` and `kube.reading`; one client per process, created on first use.
"""

from __future__ import annotations

import functools

from kubernetes import client, config
from kubernetes.config.config_exception import ConfigException

from coral_operator.api import names

CONNECTIONS = 64
"""Pooled connections to the API server: more than the handler threads plus the parallel writers."""


@functools.cache
def api_client() -> client.ApiClient:
    """The process-wide API client; in-cluster configuration first, then KUBECONFIG."""
    configuration = client.Configuration()
    try:
        config.load_incluster_config(client_configuration=configuration)
    except ConfigException:
        config.load_kube_config(client_configuration=configuration)
    # Handler threads and `applying.in_parallel` call concurrently; with urllib3's default of 10
    # pooled connections the rest are opened and discarded per request, each a new TLS handshake,
    # which at a thousand robots costs more CPU than the requests themselves.
    configuration.connection_pool_maxsize = CONNECTIONS
    api = client.ApiClient(configuration)
    # Named in audit logs and, as the field manager of every write, in managedFields (the client's
    # default is "OpenAPI-Generator", which says nothing about who wrote).
    api.user_agent = names.MANAGER
    return api


def core() -> client.CoreV1Api:
    return client.CoreV1Api(api_client())


def rbac() -> client.RbacAuthorizationV1Api:
    return client.RbacAuthorizationV1Api(api_client())


def admission() -> client.AdmissionregistrationV1Api:
    return client.AdmissionregistrationV1Api(api_client())


def custom() -> client.CustomObjectsApi:
    return client.CustomObjectsApi(api_client())


def load_api_classes() -> None:
    """Import the client's API classes now: each is a module of thousands of lines imported on first
    use, and a fleet's first pass would otherwise stall on them (0.8 s of CPU under the GIL)."""
    for build in (core, rbac, admission, custom):
        build()
