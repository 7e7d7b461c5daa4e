"""Acceptance (c): deleting an owner object makes the garbage collector delete the Pod it owns."""

from __future__ import annotations

import pytest
import yaml
from coral_testbed.cluster import Cluster
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from .manifests import robot_pod

pytestmark = pytest.mark.cluster


def _exists(core: k8s.CoreV1Api, name: str, namespace: str) -> bool:
    try:
        core.read_namespaced_pod(name, namespace)
    except ApiException as error:
        if error.status == 404:
            return False
        raise
    return True


def test_deleting_the_owner_garbage_collects_the_owned_pod(cluster: Cluster, namespace: str) -> None:
    cluster.add_robots(["r1"])
    core = k8s.CoreV1Api(cluster.api_client)
    owner = core.create_namespaced_config_map(namespace, {"metadata": {"name": "owner"}, "data": {"k": "v"}})
    pod = yaml.safe_load(robot_pod("owned", "r1"))
    pod["metadata"]["ownerReferences"] = [
        {"apiVersion": "v1", "kind": "ConfigMap", "name": "owner", "uid": owner.metadata.uid}
    ]
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=yaml.safe_dump(pod))
    # A bystander without an owner shows the collector deletes only what the owner owned.
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=robot_pod("bystander", "r1"))
    wait_for(
        lambda: core.read_namespaced_pod("owned", namespace).status.phase == "Running",
        timeout=90,
        message="pod owned to be Running",
    )

    cluster.kubectl("delete", "configmap", "owner", "-n", namespace)

    wait_for(
        lambda: not _exists(core, "owned", namespace), timeout=90, message="pod owned to be garbage-collected"
    )
    assert _exists(core, "bystander", namespace)
