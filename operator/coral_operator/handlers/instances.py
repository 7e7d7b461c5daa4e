"""Reconciles a CoralInstance: the executor's identity, ordered pod startup, per-robot status.

One idempotent, level-based pass on every event of the CoralInstance: its own changes (including
the executor's status patches) and the pokes `handlers.triggers` gives it when its pods or its
Node change or a startup stage's health timeout falls due. No timers, so no finalizer. Pods are
planned by
`planning.startup`, status by `status.instance_status`; the executor's own fields (`tree`,
`plugins`) are read, never written.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import kopf
from pydantic import ValidationError

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.handlers import events, triggers
from coral_operator.kube import applying
from coral_operator.planning import naming, pods, rbac, startup
from coral_operator.status import instance_status
from coral_operator.status.conditions import ConditionType, Reason
from coral_operator.status.transitions import Verdict, merge_conditions

CORAL = ("coral.dev", "v1alpha1", "coralinstances")


def _invalid(error: ValidationError, status: kopf.Status, generation: int | None, patch: kopf.Patch) -> None:
    message = "; ".join(f"spec.{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in error.errors())
    conditions = merge_conditions(
        list(status.get("conditions") or []),
        [
            Verdict(ConditionType.READY, False, Reason.INVALID_SPEC, message),
            Verdict(ConditionType.RECONCILING, False, Reason.INVALID_SPEC),
            Verdict(ConditionType.STALLED, True, Reason.INVALID_SPEC, message),
        ],
        generation=generation,
        now=datetime.now(UTC),
    )
    if status.get("conditions") != conditions:
        patch.status["conditions"] = conditions
        patch.status["observedGeneration"] = generation


def _apply(
    body: kopf.Body, name: str, namespace: str, uid: str, spec: CoralInstanceSpec, plan: startup.StartupPlan
) -> None:
    if any(m["metadata"]["labels"][naming.LABEL_ROLE] == "executor" for m in plan.create):
        # The ServiceAccount must exist before a pod naming it is admitted.
        applying.apply_rbac(
            rbac.build_executor_rbac(
                instance=name, namespace=namespace, instance_uid=uid, system=spec.system, robot=spec.robot
            )
        )
    for pod_name in plan.delete:
        applying.delete_pod(namespace, pod_name)
        events.info(body, "PodDeleted", f"Deleted pod {pod_name} to replace or remove it")
    for manifest in plan.create:
        if applying.create_pod(manifest):
            labels = manifest["metadata"]["labels"]
            events.info(
                body,
                "PodCreated",
                f"Created pod {manifest['metadata']['name']} for "
                f"{labels[naming.LABEL_ROLE]} {labels[naming.LABEL_COMPONENT]}",
            )
    for pod_name, labels in plan.relabel:
        applying.patch_pod_labels(namespace, pod_name, labels)


def _retire(body: kopf.Body, name: str, namespace: str, observed: list[Any], reachable: bool) -> None:
    """Stop the robot's components in reverse startup order, then remove the instance."""
    if not observed or not reachable:
        # Nothing left to stop, or no kubelet to stop it: garbage collection takes the rest.
        applying.delete_instance(namespace, name)
        events.info(body, "InstanceDeleted", f"Deleted CoralInstance {name} after stopping its components")
        return
    for pod_name in startup.plan_shutdown(observed):
        applying.delete_pod(namespace, pod_name)
        events.info(body, "PodDeleted", f"Stopped pod {pod_name} (reverse startup order)")


@kopf.on.event(*CORAL)
def reconcile_instance(
    type: str | None,
    uid: str,
    name: str,
    namespace: str,
    meta: kopf.Meta,
    status: kopf.Status,
    **kwargs: Any,
) -> None:
    """Reconcile on the instance's own changes (spec, executor reports) and on pokes."""
    if type == "DELETED":
        triggers.forget(uid)
        return
    inputs = (
        meta.get("generation"),
        (meta.get("annotations") or {}).get(triggers.ANNOTATION),
        naming.content_hash([status.get("tree"), status.get("plugins")]),
    )
    if triggers.already_handled(uid, inputs):
        return
    try:
        _reconcile_instance(name=name, namespace=namespace, uid=uid, meta=meta, status=status, **kwargs)
    except Exception:
        triggers.retry_later("coralinstances", namespace, name, uid)
        raise
    triggers.handled(uid, inputs)


def _reconcile_instance(
    name: str,
    namespace: str,
    uid: str,
    spec: kopf.Spec,
    status: kopf.Status,
    meta: kopf.Meta,
    body: kopf.Body,
    patch: kopf.Patch,
    robot_nodes: kopf.Index,
    coral_pods: kopf.Index,
    **_: Any,
) -> None:
    now = datetime.now(UTC)
    generation = meta.get("generation")
    try:
        parsed = CoralInstanceSpec.model_validate(dict(spec))
    except ValidationError as error:
        _invalid(error, status, generation, patch)
        return
    node = next(iter(robot_nodes.get(("node", parsed.node_name), [])), None)
    observed = list(coral_pods.get((namespace, name), []))
    if parsed.retiring:
        _retire(body, name, namespace, observed, node is not None and node.ready)
        return
    desired = pods.build_pods(spec=parsed, instance=name, namespace=namespace, instance_uid=uid)
    transient = {c.name for c in parsed.drivers + parsed.skillsets + parsed.executors if c.transient}
    plan = startup.plan_startup(
        desired=desired, observed=observed, transient=transient, startup=parsed.startup, now=now
    )
    _apply(body, name, namespace, uid, parsed, plan)
    if plan.wake_at is not None:
        triggers.wake_instance_at(namespace, name, plan.wake_at, now)
    view = instance_status.InstanceView(
        spec=parsed,
        node=node,
        desired=desired,
        pods=observed,
        plan=plan,
        transient=transient,
        tree=status.get("tree"),
        plugins=status.get("plugins"),
    )
    old_conditions = list(status.get("conditions") or [])
    new = instance_status.build_instance_status(
        view, old_conditions=old_conditions, generation=generation, now=now
    )
    events.on_condition_changes(body, old_conditions, new["conditions"])
    for key, value in new.items():
        if status.get(key) != value:
            patch.status[key] = value
