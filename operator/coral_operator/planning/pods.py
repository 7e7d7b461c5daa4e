"""Builds the pods of one robot: one per component, or one for the robot (docs/architecture.md).

The pod is pinned to the robot's Node, tolerates the robot dropping off the network (no eviction,
no rescheduling), shares the host network and IPC for DDS by default, gets the ROS and Coral
environment, the validated parameters (and, for executors, the tree) from immutable ConfigMaps,
and the per-robot plugin folder. Pure; called by `planning.startup` via the instance handler.

Host paths are mounted as the allowed folder they lie in (`planning.policy.host_path_volume`) with
the rest of the path as a `subPath`: the kubelet opens each name of a subPath without following a
link out of the volume and refuses the container otherwise (CreateContainerConfigError), so a
link a tenant planted in its folder cannot lead to the robot's `/etc` or another namespace's
data. The step that hands folders to the components' user runs the operator's helper image,
never a tenant's (issue 47).
"""

from __future__ import annotations

import posixpath
from dataclasses import dataclass, field
from typing import Any

from coral_core import names
from coral_core.component_image import COMPONENT_UID
from coral_core.instance_status import Role
from coral_core.names import API_VERSION
from coral_core.offline import GATE_CONTAINER

from coral_operator.api.components import Component, ExecutorComponent
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.planning import naming
from coral_operator.planning.configmaps import PARAMS_KEY, TREE_KEY
from coral_operator.planning.offline_gate import add_gate
from coral_operator.planning.policy import Policy, data_subtree, host_path_volume, is_under

CONFIG_DIR = "/etc/coral"
SERVICE_ACCOUNT_DIR = "/var/run/secrets/kubernetes.io/serviceaccount"
READY_MARKER = "ready"
FOLDERS_OWNER = "folders-owner"
OWNED_DIR = "/coral-owned"
"""Where the ownership step sees the folders it hands over (its own paths, whatever the component's)."""
DEFAULT_HELPER_IMAGE = "coral-on-kubernetes/coral-operator:0.1.0"
"""The operator's own image as the chart and deploy/coral-operator.yaml name it (Debian, has `chown`)."""
# The executor loads this with `--sink`; it writes the tree status to the robot's CoralInstance.
STATUS_SINK = "coral.executor.kubernetes_sink:create_sink"

# DaemonSet-style: a robot that drops off the network keeps its pods (no tolerationSeconds).
TOLERATIONS = [
    {"key": "node.kubernetes.io/unreachable", "operator": "Exists", "effect": "NoExecute"},
    {"key": "node.kubernetes.io/not-ready", "operator": "Exists", "effect": "NoExecute"},
    {"key": "node.kubernetes.io/unschedulable", "operator": "Exists", "effect": "NoSchedule"},
]


@dataclass(frozen=True)
class PodSettings:
    """What of the operator's configuration shapes the pods it builds."""

    policy: Policy = field(default_factory=Policy)
    """Where each namespace's host paths may lie, so each is mounted from its allowed folder."""
    helper_image: str = DEFAULT_HELPER_IMAGE
    """The image of the ownership step, which runs as root with CAP_CHOWN alone."""


class HostPathRefused(ValueError):
    """A host path lies outside every folder its namespace may mount (a CoralInstance written by hand:
    a CoralSystem asking for it is refused by the policy before any instance exists)."""


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
        # Only when given, so the pods of systems that leave it out keep their content hash.
        *(
            ["--no-progress", str(spec.tree.no_progress_seconds)]
            if spec.tree.no_progress_seconds is not None
            else []
        ),
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
            "valueFrom": {"fieldRef": {"fieldPath": f"metadata.labels['{names.LABEL_REVISION}']"}},
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


def _host_volumes(
    component: Component, namespace: str, settings: PodSettings, prefix: str = ""
) -> tuple[list, list, list]:
    """The component's device and host-path mounts, and the mounts of its folders in the namespace's
    data subtree as the ownership step sees them; `prefix` keeps names unique in a shared pod.

    Raises:
        HostPathRefused: a host path lies outside every folder the namespace may mount.
    """
    volumes: list[dict[str, Any]] = []
    mounts: list[dict[str, Any]] = []
    owned: list[dict[str, Any]] = []
    for index, device in enumerate(component.devices):
        volumes.append({"name": f"{prefix}device-{index}", "hostPath": {"path": device.host_path}})
        mounts.append(
            {"name": f"{prefix}device-{index}", "mountPath": device.container_path or device.host_path}
        )
    subtree = data_subtree(settings.policy, namespace)
    for index, host in enumerate(component.host_paths):
        name = f"{prefix}host-{index}"
        placed = host_path_volume(settings.policy, namespace, host.host_path)
        if placed is None:
            raise HostPathRefused(
                f"hostPaths[{index}].hostPath of {component.name}: {host.host_path} is outside the "
                f"folders namespace {namespace} may mount"
            )
        folder, sub_path = placed
        source: dict[str, Any] = {"path": folder}
        if folder == subtree:
            # The operator's own folder: the kubelet creates it (root, 0755) where it is missing.
            source["type"] = "DirectoryOrCreate"
        volumes.append({"name": name, "hostPath": source})
        mount: dict[str, Any] = {"name": name, "mountPath": host.mount_path, "readOnly": host.read_only}
        if sub_path:
            mount["subPath"] = sub_path
        mounts.append(mount)
        if is_under(folder, subtree):
            owned.append({**mount, "mountPath": posixpath.join(OWNED_DIR, name), "readOnly": False})
    return volumes, mounts, owned


def _volumes(
    spec: CoralInstanceSpec, namespace: str, component: Component, role: Role, settings: PodSettings
) -> tuple[list, list, list]:
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
    host_volumes, host_mounts, owned = _host_volumes(component, namespace, settings)
    plugins_owned = {"name": "plugins", "mountPath": posixpath.join(OWNED_DIR, "plugins")}
    return volumes + host_volumes, mounts + host_mounts, [plugins_owned, *owned]


def _folders_owner(owned: list[dict[str, Any]], settings: PodSettings) -> dict[str, Any]:
    """An init step giving the plugin folder and the namespace's data folders to the components' user.

    The kubelet creates `DirectoryOrCreate` host paths and missing subPaths owned by root with mode
    0755, and fsGroup does not apply to host paths, so non-root components could not write there.
    This step is root with no capability but CAP_CHOWN, runs `chown` on each mount point alone (not
    recursively, so a link a tenant planted inside is never followed) and exits. It runs the
    operator's helper image: a component's image may ship its own `chown`, and would then run as
    root on the robot (issue 47).
    """
    return {
        "name": FOLDERS_OWNER,
        "image": settings.helper_image,
        "command": [
            "chown",
            "--no-dereference",
            f"{COMPONENT_UID}:{COMPONENT_UID}",
            *(m["mountPath"] for m in owned),
        ],
        "volumeMounts": owned,
        "securityContext": {
            "runAsUser": 0,
            "runAsNonRoot": False,
            "allowPrivilegeEscalation": False,
            "capabilities": {"drop": ["ALL"], "add": ["CHOWN"]},
        },
    }


def _container(
    spec: CoralInstanceSpec, instance: str, component: Component, role: Role, mounts: list[dict[str, Any]]
) -> dict[str, Any]:
    """One component's container, without its probes."""
    container: dict[str, Any] = {
        "name": component.name,
        "image": component.image,
        "env": _env(spec, instance, component, role),
        "volumeMounts": mounts,
        "securityContext": _security(component),
    }
    command = list(component.command) or (
        executor_command(spec) if role == "executor" and not component.args else []
    )
    args = list(component.args)
    groot2 = component.groot2 if isinstance(component, ExecutorComponent) else None
    if groot2:
        # Our own command takes the flags; otherwise they follow the user's arguments, which the
        # image's entrypoint (`python -m coral.executor ...`) or the user's command receives.
        (command if command and not component.command else args).extend(groot2.executor_args())
    metrics = component.metrics if isinstance(component, ExecutorComponent) else None
    if metrics:
        (command if command and not component.command else args).extend(metrics.executor_args())
        container["ports"] = [
            {"name": _metrics_port_name(spec, component), "containerPort": metrics.port, "protocol": "TCP"}
        ]
    if command:
        container["command"] = command
    if args:
        container["args"] = args
    if component.image_pull_policy:
        container["imagePullPolicy"] = component.image_pull_policy
    if component.resources:
        container["resources"] = component.resources.to_wire()
    return container


def _metrics_port_name(spec: CoralInstanceSpec, component: Component) -> str:
    """`metrics`, which a PodMonitor selects; numbered when several executors of one robot's pod
    (`PodPerRobot`) serve metrics, as port names are unique in a pod."""
    serving = [e.name for e in spec.executors if e.metrics]
    return "metrics" if len(serving) == 1 else f"metrics-{serving.index(component.name)}"


def _host_namespaces(spec: CoralInstanceSpec) -> dict[str, Any]:
    host = spec.ros.network == "Host"
    return {
        "hostNetwork": host,
        "hostIPC": host,
        "dnsPolicy": "ClusterFirstWithHostNet" if host else "ClusterFirst",
    }


def _pod(
    *,
    name_part: str,
    labels: dict[str, str],
    pod_spec: dict[str, Any],
    instance: str,
    namespace: str,
    instance_uid: str,
    annotations: dict[str, str] | None = None,
) -> dict[str, Any]:
    unhashed = {k: v for k, v in labels.items() if k != names.LABEL_REVISION}
    # The name is derived from the hash, so the hash must not cover the name. Nor the helper's image:
    # the step has run once a pod started, and an operator upgrade bringing a new one must not
    # restart every robot's components.
    pod_hash = naming.content_hash({"labels": unhashed, "spec": _without_helper_image(pod_spec)})
    return {
        "apiVersion": "v1",
        "kind": "Pod",
        "metadata": {
            "name": naming.pod_name(instance, name_part, pod_hash),
            "namespace": namespace,
            "labels": labels,
            "annotations": {names.ANNOTATION_POD_HASH: pod_hash, **(annotations or {})},
            "ownerReferences": [
                naming.owner_reference(API_VERSION, names.INSTANCE_KIND, instance, instance_uid)
            ],
        },
        "spec": pod_spec,
    }


def build_pod(
    *,
    spec: CoralInstanceSpec,
    instance: str,
    namespace: str,
    instance_uid: str,
    component: Component,
    role: Role,
    settings: PodSettings,
) -> dict[str, Any]:
    """The pod manifest of one component (`PodPerComponent`), with its content hash in an annotation.

    The hash covers everything but the revision label, so a new revision that leaves this
    component unchanged relabels the pod instead of restarting it; the name ends in a digest of the
    hash, so a changed pod comes back under a new name.
    """
    volumes, mounts, owned = _volumes(spec, namespace, component, role, settings)
    container = _container(spec, instance, component, role, mounts)
    probe = _probe(spec, component, role)
    if probe:
        container["readinessProbe"] = probe
    pod_spec: dict[str, Any] = {
        "nodeName": spec.node_name,
        "tolerations": [dict(t) for t in TOLERATIONS],
        **_host_namespaces(spec),
        # An executor runs a mission: once its tree succeeded (exit 0) the pod stays Succeeded, like
        # a Job, instead of starting the mission over; a failed or crashed mission is retried.
        "restartPolicy": "OnFailure" if component.transient or role == "executor" else "Always",
        "enableServiceLinks": False,
        "automountServiceAccountToken": role == "executor",
        "containers": [container],
        "volumes": volumes,
    }
    if not (component.run_as_root or component.privileged):
        pod_spec["initContainers"] = [_folders_owner(owned, settings)]
    if role == "executor":
        pod_spec["serviceAccountName"] = naming.executor_account_name(spec.system)
    labels = naming.pod_labels(spec.system, spec.robot, instance, component.name, role, spec.revision)
    offline = add_gate(
        spec=spec,
        namespace=namespace,
        part=component.name,
        pod_spec=pod_spec,
        labels=labels,
        image=settings.helper_image,
    )
    return _pod(
        name_part=component.name,
        labels=labels,
        pod_spec=pod_spec,
        instance=instance,
        namespace=namespace,
        instance_uid=instance_uid,
        annotations=offline,
    )


def _startup_probe(spec: CoralInstanceSpec, probe: dict[str, Any]) -> dict[str, Any]:
    """The readiness gate as a sidecar's startup probe: the kubelet starts the next container once it
    passes. It may take the whole health timeout before the kubelet restarts the sidecar."""
    period = probe["periodSeconds"]
    patience = -(-spec.startup.health_timeout_seconds // period)
    return {**probe, "failureThreshold": max(probe["failureThreshold"], patience)}


def _executor_token_volume() -> dict[str, Any]:
    # The same files the kubelet's automount gives, but mounted into the executors only: the
    # drivers and skillsets sharing the pod get no API identity at all.
    return {
        "name": "executor-token",
        "projected": {
            "sources": [
                {"serviceAccountToken": {"path": "token", "expirationSeconds": 3607}},
                {"configMap": {"name": "kube-root-ca.crt", "items": [{"key": "ca.crt", "path": "ca.crt"}]}},
                {
                    "downwardAPI": {
                        "items": [{"path": "namespace", "fieldRef": {"fieldPath": "metadata.namespace"}}]
                    }
                },
            ]
        },
    }


def build_robot_pod(
    *, spec: CoralInstanceSpec, instance: str, namespace: str, instance_uid: str, settings: PodSettings
) -> dict[str, Any]:
    """The one pod of a robot (`PodPerRobot`): drivers, then skillsets, as native sidecars, executors
    as the main containers, the plugin location an `emptyDir` they all share.

    Sidecars are `initContainers` with `restartPolicy: Always`, so the kubelet starts them in compose
    order, each once the previous one's startup probe passed, keeps them running beside the
    executors and stops them in reverse once the executors end. A transient driver or skillset is a
    plain init container: it runs to completion before the next one starts.
    """
    volumes: list[dict[str, Any]] = [
        {"name": "plugins", "emptyDir": {}},
        {
            "name": "config",
            "projected": {
                "sources": [
                    {"configMap": {"name": spec.parameters.config_map}},
                    {"configMap": {"name": spec.tree.config_map}},
                ]
            },
        },
    ]
    shared = [
        {"name": "plugins", "mountPath": spec.plugins.mount_path},
        {"name": "config", "mountPath": CONFIG_DIR, "readOnly": True},
    ]
    sidecars: list[dict[str, Any]] = []
    mains: list[dict[str, Any]] = []
    roles: list[tuple[Role, list[Component]]] = [
        ("driver", spec.drivers),
        ("skillset", spec.skillsets),
        ("executor", spec.executors),
    ]
    index = 0
    owned: list[dict[str, Any]] = []
    for role, components in roles:
        for component in components:
            host_volumes, host_mounts, component_owned = _host_volumes(
                component, namespace, settings, prefix=f"c{index}-"
            )
            index += 1
            volumes += host_volumes
            if not (component.run_as_root or component.privileged):
                owned += component_owned
            mounts = [dict(m) for m in shared] + host_mounts
            if role == "executor":
                mounts.append({"name": "executor-token", "mountPath": SERVICE_ACCOUNT_DIR, "readOnly": True})
            container = _container(spec, instance, component, role, mounts)
            probe = _probe(spec, component, role)
            if role == "executor" or component.transient:
                # A sidecar is restarted whatever its exit code, so a transient component (which may
                # finish, like a bag player) runs beside the executors, after every sidecar started.
                if probe:
                    container["readinessProbe"] = probe
                mains.append(container)
                continue
            container["restartPolicy"] = "Always"
            if probe:
                container["startupProbe"] = _startup_probe(spec, probe)
                container["readinessProbe"] = probe
            sidecars.append(container)
    volumes.append(_executor_token_volume())
    pod_spec: dict[str, Any] = {
        "nodeName": spec.node_name,
        "tolerations": [dict(t) for t in TOLERATIONS],
        **_host_namespaces(spec),
        # The executors' policy, as for their own pods; the sidecars restart whatever it says.
        "restartPolicy": "OnFailure",
        "enableServiceLinks": False,
        "automountServiceAccountToken": False,
        "serviceAccountName": naming.executor_account_name(spec.system),
        # The plugin folder is an emptyDir the kubelet makes writable to all; only the namespace's
        # data folders need handing over, before the first sidecar starts.
        "initContainers": ([_folders_owner(owned, settings)] if owned else []) + sidecars,
        "containers": mains,
        "volumes": volumes,
    }
    members = [f"{role}:{c.name}" for role, components in roles for c in components]
    labels = naming.robot_pod_labels(spec.system, spec.robot, instance, spec.revision)
    offline = add_gate(
        spec=spec,
        namespace=namespace,
        part="robot",
        pod_spec=pod_spec,
        labels=labels,
        image=settings.helper_image,
    )
    shape = naming.content_hash(_without_images(pod_spec))
    return _pod(
        name_part="robot",
        labels=labels,
        pod_spec=pod_spec,
        instance=instance,
        namespace=namespace,
        instance_uid=instance_uid,
        annotations={
            names.ANNOTATION_COMPONENTS: ",".join(members),
            names.ANNOTATION_SHAPE_HASH: shape,
            **offline,
        },
    )


def _without_helper_image(pod_spec: dict[str, Any]) -> dict[str, Any]:
    inits = pod_spec.get("initContainers")
    if not inits:
        return pod_spec
    return {
        **pod_spec,
        "initContainers": [
            {**c, "image": ""} if c["name"] in (FOLDERS_OWNER, GATE_CONTAINER) else c for c in inits
        ],
    }


def _without_images(pod_spec: dict[str, Any]) -> dict[str, Any]:
    return {
        **pod_spec,
        "initContainers": [{**c, "image": ""} for c in pod_spec["initContainers"]],
        "containers": [{**c, "image": ""} for c in pod_spec["containers"]],
    }


def container_images(manifest: dict[str, Any]) -> dict[str, str]:
    """Every container's image by container name (init containers included)."""
    spec = manifest["spec"]
    return {c["name"]: c["image"] for c in [*spec.get("initContainers", []), *spec["containers"]]}


def build_pods(
    *,
    spec: CoralInstanceSpec,
    instance: str,
    namespace: str,
    instance_uid: str,
    settings: PodSettings | None = None,
) -> list[dict[str, Any]]:
    """The robot's pods: with `PodPerRobot` its one pod, else every component's, in startup order.

    Raises:
        HostPathRefused: a host path lies outside every folder the namespace may mount.
    """
    settings = settings or PodSettings()
    if spec.layout == "PodPerRobot":
        robot_pod = build_robot_pod(
            spec=spec, instance=instance, namespace=namespace, instance_uid=instance_uid, settings=settings
        )
        return [robot_pod]
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
            settings=settings,
        )
        for role, components in groups
        for c in components
    ]
