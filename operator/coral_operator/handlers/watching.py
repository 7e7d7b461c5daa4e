"""kopf's watch events, translated into keys on the controller's work queue; nothing else.

Every handler hands kopf's indexes to the controller (its workers read them between events) and
names what changed; the passes run later on the queue's workers (`reconcile.controller`). Event
handlers only (no change handlers, no timers), so kopf puts no finalizer on anything.
"""

from __future__ import annotations

from typing import Any

import kopf
from coral_core import names

from coral_operator.handlers.filters import CORAL_POD_LABELS, ROBOT_NODE_LABELS
from coral_operator.planning.pull_state import PULL_ROLE
from coral_operator.reconcile.controller import Controller

CORAL_SYSTEMS = (names.GROUP, names.VERSION, names.SYSTEM_PLURAL)
CORAL_INSTANCES = (names.GROUP, names.VERSION, names.INSTANCE_PLURAL)
INDEXES = (
    "robot_nodes",
    "coral_pods",
    "coral_instances",
    "coral_systems",
    "revision_config_maps",
)


def _controller(memo: kopf.Memo, kwargs: dict[str, Any]) -> Controller:
    controller: Controller = memo["controller"]
    controller.start(**{name: kwargs[name] for name in INDEXES})
    return controller


@kopf.on.event(*CORAL_SYSTEMS)
async def coral_system_changed(
    type: str | None, namespace: str, name: str, uid: str, body: kopf.Body, memo: kopf.Memo, **kwargs: Any
) -> None:
    _controller(memo, kwargs).on_system(
        deleted=type == "DELETED", namespace=namespace, name=name, uid=uid, body=body
    )


@kopf.on.event(*CORAL_INSTANCES)
async def coral_instance_changed(
    type: str | None, namespace: str, name: str, uid: str, body: kopf.Body, memo: kopf.Memo, **kwargs: Any
) -> None:
    _controller(memo, kwargs).on_instance(
        deleted=type == "DELETED", namespace=namespace, name=name, uid=uid, body=body
    )


@kopf.on.event("pods", labels=CORAL_POD_LABELS)
async def coral_pod_changed(namespace: str, labels: kopf.Labels, memo: kopf.Memo, **kwargs: Any) -> None:
    pre_pull = labels.get(names.LABEL_ROLE) == PULL_ROLE
    _controller(memo, kwargs).on_pod(
        namespace=namespace,
        instance=labels[names.LABEL_INSTANCE],
        pre_pull_of=labels.get(names.LABEL_SYSTEM) if pre_pull else None,
    )


@kopf.on.event("nodes", labels=ROBOT_NODE_LABELS)
async def robot_node_changed(
    type: str | None,
    name: str,
    labels: kopf.Labels,
    annotations: kopf.Annotations,
    spec: kopf.Spec,
    status: kopf.Status,
    memo: kopf.Memo,
    **kwargs: Any,
) -> None:
    _controller(memo, kwargs).on_robot_node(
        deleted=type == "DELETED", name=name, labels=labels, spec=spec, status=status, annotations=annotations
    )


@kopf.on.event("configmaps")
async def config_map_changed(namespace: str, name: str, memo: kopf.Memo, **kwargs: Any) -> None:
    _controller(memo, kwargs).on_config_map(namespace=namespace, name=name)
