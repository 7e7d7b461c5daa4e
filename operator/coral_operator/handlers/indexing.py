"""In-memory indexes of robot Nodes, component pods, CoralInstances, CoralSystems and the systems'
revision ConfigMaps, kept by kopf.

The reconcilers read these (`reconcile.indexes`) instead of listing the API on every pass; a pass
that runs before an index caught up meets 409 on create, which `kube.applying` treats as done.

The functions are coroutines although they never wait: kopf runs a plain function in its thread
pool, a hop per index and watch event that at a thousand robots costs the event loop more than
building the record does.
"""

from __future__ import annotations

from typing import Any

import kopf
from coral_core import names

from coral_operator.handlers.filters import CORAL_POD_LABELS, REVISION_CONFIG_MAP_LABELS, ROBOT_NODE_LABELS
from coral_operator.kube import observing
from coral_operator.reconcile.indexes import (
    ALL_ROBOTS,
    config_maps_of_system,
    instance_named,
    instances_of_system,
    instances_on_node,
)


@kopf.index("nodes", labels=ROBOT_NODE_LABELS)
async def robot_nodes(
    name: str,
    labels: kopf.Labels,
    annotations: kopf.Annotations,
    spec: kopf.Spec,
    status: kopf.Status,
    **_: Any,
) -> dict[Any, Any]:
    robot = observing.robot_node(name, labels, status, spec, annotations)
    if robot is None:
        return {}
    return {ALL_ROBOTS: robot, ("node", name): robot}


@kopf.index("pods", labels=CORAL_POD_LABELS)
async def coral_pods(namespace: str, labels: kopf.Labels, body: kopf.Body, **_: Any) -> dict[Any, Any]:
    # A robot pod (`PodPerRobot`) gives one record per component; readers flatten them.
    return {(namespace, labels[names.LABEL_INSTANCE]): observing.observed_pods(body)}


@kopf.index(names.GROUP, names.VERSION, names.INSTANCE_PLURAL)
async def coral_instances(
    namespace: str, name: str, spec: kopf.Spec, body: kopf.Body, memo: kopf.Memo, **_: Any
) -> dict[Any, Any]:
    shared = memo["controller"].memory.specs.share(body)
    return {
        instances_of_system(namespace, spec.get("system", "")): observing.observed_instance(body, shared),
        instance_named(namespace, name): observing.instance_record(body, shared),
        instances_on_node(spec.get("nodeName", "")): (namespace, name),
    }


@kopf.index(names.GROUP, names.VERSION, names.SYSTEM_PLURAL)
async def coral_systems(namespace: str, name: str, body: kopf.Body, **_: Any) -> dict[Any, Any]:
    return {(namespace, name): observing.system_record(body)}


@kopf.index("configmaps", labels=REVISION_CONFIG_MAP_LABELS)
async def revision_config_maps(
    namespace: str, name: str, labels: kopf.Labels, meta: kopf.Meta, **_: Any
) -> dict[Any, Any]:
    # The owners tell the system's ConfigMaps from those of an earlier system of the same name,
    # which the garbage collector is about to delete.
    owners = tuple(reference.get("uid", "") for reference in meta.get("ownerReferences") or [])
    return {config_maps_of_system(namespace, labels[names.LABEL_SYSTEM]): (name, owners)}
