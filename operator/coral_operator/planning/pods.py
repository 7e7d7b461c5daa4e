"""Builds the pod of one component on one robot (DESIGN sections 3 and 4).

The pod is pinned to the robot's Node, tolerates the robot dropping off the network (no eviction,
no rescheduling), shares the host network and IPC for DDS by default, gets the ROS and Coral
environment, the validated parameters (and, for executors, the tree) from immutable ConfigMaps,
and the per-robot plugin folder. Pure; called by `planning.startup` via the instance handler.
"""

from __future__ import annotations

import posixpath
from typing import Any

from coral_operator.api.base import API_VERSION
from coral_operator.api.components import Component, Role
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.planning import naming
from coral_operator.planning.configmaps import PARAMS_KEY, TREE_KEY

CONFIG_DIR = "/etc/coral"
READY_MARKER = "ready"
# The executor loads this with `--sink`; it writes the tree status to the robot's CoralInstance.
STATUS_SINK = "coral_operator.sink.kubernetes:create_sink"

# DaemonSet-style: a robot that drops off the network keeps its pods (no tolerationSeconds).
TOLERATIONS = [
    {"key": "node.kubernetes.io/unreachable", "operator": "Exists", "effect": "NoExecute"},
    {"key": "node.kubernetes.io/not-ready", "operator": "Exists", "effect": "NoExecute"},
    {"key": "node.kubernetes.io/unschedulable", "operator": "Exists", "effect": "NoSchedule"},
]


def plugin_host_path(spec: CoralInstanceSpec, namespace: str) -> str:
    """The robot folder shared by the system's components: one per system and namespace."""
    return posixpath.join(spec.plugins.host_path_root, namespace, spec.system)


def executor_command(spec: CoralInstanceSpec) -> list[str]:
    """The executor's command when its component gives none."""
    return [
        "python",
        "-m",
        "coral.executor",
        "--tree",
        posixpath.join(CONFIG_DIR, TREE_KEY),
        "--plugins",
        spec.plugins.mount_path,
        "--params",
        posixpath.join(CONFIG_DIR, PARAMS_KEY),
        "--rate",
        f"{spec.tree.tick_rate_hz:g}",
        "--sink",
        STATUS_SINK,
        "--hostname",
        spec.robot,
        *(["--main-tree", spec.tree.main_tree_id] if spec.tree.main_tree_id else []),
    ]


def _env(spec: CoralInstanceSpec, instance: str, component: Component, role: Role) -> list[dict[str, Any]]:
    values = {
        "ROS_DOMAIN_ID": str(spec.ros.domain_id),
        "RMW_IMPLEMENTATION": spec.ros.rmw_implementation,
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST" if spec.ros.localhost_only else "SUBNET",
        "ROS_DISTRO": spec.ros.distro,
        "CORAL_SYSTEM": spec.system,
        "CORAL_ROBOT": spec.robot,
        "CORAL_INSTANCE": instance,
        "CORAL_COMPONENT": component.name,
        "CORAL_HOSTNAME": spec.robot,
        "CORAL_ROLE": role,
        "CORAL_PLUGIN_DIR": spec.plugins.mount_path,
        "CORAL_PARAMS_FILE": posixpath.join(CONFIG_DIR, PARAMS_KEY),
    }
    if role == "executor":
        values |= {
            "CORAL_TREE_FILE": posixpath.join(CONFIG_DIR, TREE_KEY),
            "CORAL_TICK_RATE_HZ": f"{spec.tree.tick_rate_hz:g}",
            "CORAL_STATUS_SINK": "kubernetes",
        }
        if spec.tree.main_tree_id:
            values["CORAL_MAIN_TREE"] = spec.tree.main_tree_id
    env: list[dict[str, Any]] = [{"name": k, "value": v} for k, v in values.items()]
    env.append({"name": "CORAL_NAMESPACE", "valueFrom": {"fieldRef": {"fieldPath": "metadata.namespace"}}})
    env.append({"name": "CORAL_POD", "valueFrom": {"fieldRef": {"fieldPath": "metadata.name"}}})
    # Read from the label at container start, so a new revision does not change this pod's spec.
    env.append(
        {
            "name": "CORAL_REVISION",
            "valueFrom": {"fieldRef": {"fieldPath": f"metadata.labels['{naming.LABEL_REVISION}']"}},
        }
    )
    # The user's variables come last so they can override ours deliberately.
    env.extend({"name": e.name, "value": e.value} for e in component.env)
    return env


def _probe(spec: CoralInstanceSpec, component: Component, role: Role) -> dict[str, Any] | None:
    readiness = component.readiness
    command = list(readiness.exec) if readiness else []
    use_marker = (
        readiness.plugin_marker if readiness and readiness.plugin_marker is not None else role == "skillset"
    )
    if not command and use_marker:
        command = ["test", "-f", posixpath.join(spec.plugins.mount_path, component.name, READY_MARKER)]
    if not command:
        return None
    return {
        "exec": {"command": command},
        "initialDelaySeconds": readiness.initial_delay_seconds if readiness else 0,
        "periodSeconds": readiness.period_seconds if readiness else 2,
        "failureThreshold": readiness.failure_threshold if readiness else 3,
    }


def _security(component: Component) -> dict[str, Any]:
    if component.privileged:
        return {"privileged": True}
    if component.run_as_root:
        return {"allowPrivilegeEscalation": False}
    # A ROS 2 process needs no capability; dropping them all is what Pod Security's restricted level asks.
    return {"runAsNonRoot": True, "allowPrivilegeEscalation": False, "capabilities": {"drop": ["ALL"]}}


def _volumes(spec: CoralInstanceSpec, namespace: str, component: Component, role: Role) -> tuple[list, list]:
    sources = [{"configMap": {"name": spec.parameters.config_map}}]
    if role == "executor":
        sources.append({"configMap": {"name": spec.tree.config_map}})
    volumes: list[dict[str, Any]] = [
        {
            "name": "plugins",
            "hostPath": {"path": plugin_host_path(spec, namespace), "type": "DirectoryOrCreate"},
        },
        {"name": "config", "projected": {"sources": sources}},
    ]
    mounts: list[dict[str, Any]] = [
        {"name": "plugins", "mountPath": spec.plugins.mount_path},
        {"name": "config", "mountPath": CONFIG_DIR, "readOnly": True},
    ]
    for index, device in enumerate(component.devices):
        volumes.append({"name": f"device-{index}", "hostPath": {"path": device.host_path}})
        mounts.append({"name": f"device-{index}", "mountPath": device.container_path or device.host_path})
    for index, host in enumerate(component.host_paths):
        volumes.append({"name": f"host-{index}", "hostPath": {"path": host.host_path}})
        mounts.append({"name": f"host-{index}", "mountPath": host.mount_path, "readOnly": host.read_only})
    return volumes, mounts


def build_pod(
    *,
    spec: CoralInstanceSpec,
    instance: str,
    namespace: str,
    instance_uid: str,
    component: Component,
    role: Role,
) -> dict[str, Any]:
    """The pod manifest of one component, with its content hash in an annotation.

    The hash covers everything but the revision label, so a new revision that leaves this
    component unchanged relabels the pod instead of restarting it; the name ends in a digest of the
    hash, so a changed pod comes back under a new name.
    """
    volumes, mounts = _volumes(spec, namespace, component, role)
    container: dict[str, Any] = {
        "name": component.name,
        "image": component.image,
        "env": _env(spec, instance, component, role),
        "volumeMounts": mounts,
        "securityContext": _security(component),
    }
    command = component.command or (
        executor_command(spec) if role == "executor" and not component.args else []
    )
    if command:
        container["command"] = command
    if component.args:
        container["args"] = list(component.args)
    if component.image_pull_policy:
        container["imagePullPolicy"] = component.image_pull_policy
    if component.resources:
        container["resources"] = component.resources.to_wire()
    probe = _probe(spec, component, role)
    if probe:
        container["readinessProbe"] = probe
    host = spec.ros.network == "Host"
    pod_spec: dict[str, Any] = {
        "nodeName": spec.node_name,
        "tolerations": [dict(t) for t in TOLERATIONS],
        "hostNetwork": host,
        "hostIPC": host,
        "dnsPolicy": "ClusterFirstWithHostNet" if host else "ClusterFirst",
        # An executor runs a mission: once its tree succeeded (exit 0) the pod stays Succeeded, like
        # a Job, instead of starting the mission over; a failed or crashed mission is retried.
        "restartPolicy": "OnFailure" if component.transient or role == "executor" else "Always",
        "enableServiceLinks": False,
        "automountServiceAccountToken": role == "executor",
        "containers": [container],
        "volumes": volumes,
    }
    if role == "executor":
        pod_spec["serviceAccountName"] = naming.executor_account_name(instance)
    labels = naming.pod_labels(spec.system, spec.robot, instance, component.name, role, spec.revision)
    unhashed = {k: v for k, v in labels.items() if k != naming.LABEL_REVISION}
    # The name is derived from the hash, so the hash must not cover the name.
    pod_hash = naming.content_hash({"labels": unhashed, "spec": pod_spec})
    return {
        "apiVersion": "v1",
        "kind": "Pod",
        "metadata": {
            "name": naming.pod_name(instance, component.name, pod_hash),
            "namespace": namespace,
            "labels": labels,
            "annotations": {naming.ANNOTATION_POD_HASH: pod_hash},
            "ownerReferences": [naming.owner_reference(API_VERSION, "CoralInstance", instance, instance_uid)],
        },
        "spec": pod_spec,
    }


def build_pods(
    *, spec: CoralInstanceSpec, instance: str, namespace: str, instance_uid: str
) -> list[dict[str, Any]]:
    """Every component's pod, in startup order: drivers, skillsets, executors."""
    groups: tuple[tuple[Role, list[Component]], ...] = (
        ("driver", spec.drivers),
        ("skillset", spec.skillsets),
        ("executor", spec.executors),
    )
    return [
        build_pod(
            spec=spec,
            instance=instance,
            namespace=namespace,
            instance_uid=instance_uid,
            component=c,
            role=role,
        )
        for role, components in groups
        for c in components
    ]
