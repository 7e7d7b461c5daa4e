"""The shared Kubernetes API client of the operator process (in-cluster or from KUBECONFIG).

Used by `kube.applying` and `kube.reading`; one client per process, created on first use.
"""

from __future__ import annotations

import functools

from kubernetes import client, config
from kubernetes.config.config_exception import ConfigException


@functools.cache
def api_client() -> client.ApiClient:
    """The process-wide API client; in-cluster configuration first, then KUBECONFIG."""
    try:
        config.load_incluster_config()
    except ConfigException:
        config.load_kube_config()
    return client.ApiClient()


def core() -> client.CoreV1Api:
    return client.CoreV1Api(api_client())


def rbac() -> client.RbacAuthorizationV1Api:
    return client.RbacAuthorizationV1Api(api_client())


def custom() -> client.CustomObjectsApi:
    return client.CustomObjectsApi(api_client())
