"""Reads the Node Leases in which kubelets (and kwok) heartbeat every ten seconds.

A Node's Ready condition carries a heartbeat that the kubelet refreshes only every few minutes
when nothing changes, so the Lease is the truthful "last seen" of a robot. Read only for robots
that are unreachable (then the value stops changing), so it costs nothing while robots are fine.
Called by the instance reconciler (`reconcile.instances`).
"""

from __future__ import annotations

from datetime import datetime

from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_operator.kube import client

NODE_LEASE_NAMESPACE = "kube-node-lease"


def read_renew_time(node_name: str) -> datetime | None:
    """When the Node's kubelet last renewed its Lease; None if it has none or it cannot be read."""
    try:
        lease = k8s.CoordinationV1Api(client.api_client()).read_namespaced_lease(
            node_name, NODE_LEASE_NAMESPACE
        )
    except ApiException as error:
        if error.status in (403, 404):
            return None
        raise
    return lease.spec.renew_time if lease.spec else None
