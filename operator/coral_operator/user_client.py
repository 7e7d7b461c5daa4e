"""The Kubernetes API client of the `coral` verbs people run (`coral rollout`, `coral groot2`): in a
pod its ServiceAccount, elsewhere the user's kubeconfig, so their own identity and RBAC apply."""

from __future__ import annotations

import os

from kubernetes import client as k8s
from kubernetes import config as k8s_config


def user_api_client() -> k8s.ApiClient:
    try:
        k8s_config.load_incluster_config()
    except k8s_config.ConfigException:
        # Read $KUBECONFIG now: the client's default location is fixed when it is imported.
        k8s_config.load_kube_config(config_file=os.environ.get("KUBECONFIG"))
    return k8s.ApiClient()
