"""Reconciles a CoralSystem: validate, choose robots, create/update/delete CoralInstances, report.

One idempotent, level-based pass on every event of the CoralSystem: its own changes, and the
pokes `handlers.triggers` gives it when its robots, instances or source ConfigMaps change. No
timers and no change handlers, so kopf puts no finalizer on it. The decisions are made by
`planning`, the writes by `kube.applying`, the status by `status.system_status`.
"""

from __future__ import annotations

import logging
from datetime import UTC, datetime
from typing import Any

import kopf
from pydantic import ValidationError

from coral_operator import config
from coral_operator.api.system import CoralSystemSpec, SourceSpec
from coral_operator.handlers import events, rollouts, triggers
from coral_operator.handlers.indexing import ALL_ROBOTS
from coral_operator.kube import applying
from coral_operator.planning import configmaps, instances, policy, rbac, selection, validation
from coral_operator.status import system_status
from coral_operator.status.conditions import Reason

CONFIG = config.from_environment()
log = logging.getLogger(__name__)
CORAL = ("coral.dev", "v1alpha1", "coralsystems")


def _format_validation(error: ValidationError) -> str:
    parts = []
    for item in error.errors():
        where = "spec." + ".".join(str(p) for p in item["loc"]) if item["loc"] else "spec"
        parts.append(f"{where}: {item['msg']}")
    return "; ".join(parts)


def _read_source(
    namespace: str, name: str, source: SourceSpec, field: str
) -> tuple[str, str] | system_status.Problem:
    """(text, filename for messages) of an inline or ConfigMap file, or why it cannot be read."""
    if source.inline is not None:
        return source.inline, f"coralsystem/{name} spec.{field}.inline"
    ref = source.config_map_ref
    assert ref is not None  # the model guarantees exactly one of the two
    text = applying.read_config_map_key(namespace, ref.name, ref.key)
    if text is None:
        return system_status.Problem(
            Reason.CONFIG_MAP_NOT_FOUND,
            f"spec.{field}.configMapRef: ConfigMap {ref.name} has no key {ref.key}.",
        )
    return text, f"configmap/{ref.name}/{ref.key}"


def _prepare(name: str, namespace: str, spec: CoralSystemSpec) -> tuple[str, str] | system_status.Problem:
    """Validated (tree text, parameters text), or the problem that stalls the system."""
    tree = _read_source(namespace, name, spec.tree, "tree")
    if isinstance(tree, system_status.Problem):
        return tree
    params = _read_source(namespace, name, spec.parameters, "parameters")
    if isinstance(params, system_status.Problem):
        return params
    problems = validation.validate_tree(
        tree[0],
        tree[1],
        spec.tree.main_tree_id,
        spec.tree.files,
        files_label=f"coralsystem/{name} spec.tree.files",
    )
    if problems:
        return system_status.Problem(Reason.INVALID_TREE, _listed(problems))
    problems = validation.validate_parameters(params[0], params[1])
    if problems:
        return system_status.Problem(Reason.INVALID_PARAMETERS, _listed(problems))
    denied = policy.evaluate_policy(namespace, spec, CONFIG.policy)
    if denied:
        return system_status.Problem(
            Reason.POLICY_DENIED, "Refused by the operator's policy: " + _listed(denied)
        )
    return tree[0], params[0]


def _listed(problems: list[str], shown: int = 20) -> str:
    """The first problems, then how many more: a tree can have thousands."""
    more = len(problems) - shown
    return "; ".join(problems[:shown]) + (f"; and {more} more problems" if more > 0 else "")


def _names(names: list[str]) -> str:
    shown = ", ".join(names[:10])
    return shown + (f" and {len(names) - 10} more" if len(names) > 10 else "")


def _apply_plan(body: kopf.Body, namespace: str, plan: instances.InstancePlan) -> None:
    # One Event per kind of change and pass, not per robot: a fleet has thousands of them.
    created = [
        m["metadata"]["name"]
        for m, new in zip(
            plan.create, applying.in_parallel(applying.create_instance, plan.create), strict=True
        )
        if new
    ]
    if created:
        events.info(body, "InstancesCreated", f"Created {len(created)} CoralInstances: {_names(created)}")
    applying.in_parallel(applying.update_instance, plan.update)
    if plan.update:
        revision = plan.update[0]["spec"]["revision"]
        updated = [m["metadata"]["name"] for m in plan.update]
        events.info(
            body,
            "InstancesUpdated",
            f"Moved {len(updated)} CoralInstances to revision {revision}: {_names(updated)}",
        )
    applying.in_parallel(lambda name: applying.retire_instance(namespace, name), plan.retire)
    if plan.retire:
        events.info(
            body, "InstancesRetiring", f"Stopping in reverse order, their robots left: {_names(plan.retire)}"
        )
    applying.in_parallel(lambda name: applying.delete_instance(namespace, name), plan.delete)
    if plan.delete:
        events.info(
            body, "InstancesDeleted", f"Deleted CoralInstances whose robots left: {_names(plan.delete)}"
        )


@kopf.on.event(*CORAL)
def reconcile_system(
    type: str | None, uid: str, name: str, namespace: str, meta: kopf.Meta, **kwargs: Any
) -> None:
    """Reconcile on the system's own changes and on pokes; its own status writes change nothing."""
    if type == "DELETED":
        triggers.forget(uid)
        return
    annotations = meta.get("annotations") or {}
    # `coral rollout undo` and `resume` (annotations) are inputs too.
    inputs = (
        meta.get("generation"),
        annotations.get(triggers.ANNOTATION),
        annotations.get(rollouts.UNDO_ANNOTATION),
        annotations.get(rollouts.RESUME_ANNOTATION),
    )
    if triggers.already_handled(uid, inputs):
        return
    try:
        _reconcile_system(name=name, namespace=namespace, uid=uid, meta=meta, **kwargs)
    except Exception:
        triggers.retry_later("coralsystems", namespace, name, uid)
        raise
    triggers.handled(uid, inputs)


def _reconcile_system(
    name: str,
    namespace: str,
    uid: str,
    spec: kopf.Spec,
    status: kopf.Status,
    meta: kopf.Meta,
    body: kopf.Body,
    patch: kopf.Patch,
    robot_nodes: kopf.Index,
    coral_instances: kopf.Index,
    **_: Any,
) -> None:
    now = datetime.now(UTC)
    observed = list(coral_instances.get((namespace, name), []))
    problem: system_status.Problem | None = None
    matched = len(observed)
    revision = status.get("revision")
    fleet: rollouts.FleetPlan | None = None
    try:
        parsed = CoralSystemSpec.model_validate(dict(spec))
    except ValidationError as error:
        parsed = None
        problem = system_status.Problem(Reason.INVALID_SPEC, _format_validation(error))
    if parsed is not None:
        try:
            prepared = _prepare(name, namespace, parsed)
        except Exception as error:  # noqa: BLE001 - one system's input must not stop the others
            if applying.is_api_error(error):
                raise  # reading a source ConfigMap failed: kopf retries
            log.warning(
                "Validating CoralSystem %s/%s failed: %s: %s", namespace, name, type(error).__name__, error
            )
            prepared = system_status.Problem(
                Reason.VALIDATION_FAILED, f"The spec could not be validated ({type(error).__name__})."
            )
        if isinstance(prepared, system_status.Problem):
            problem = prepared
        else:
            try:
                matched, fleet = _deploy(
                    body, name, namespace, uid, parsed, prepared, observed, robot_nodes, status
                )
            except Exception as error:
                refused = applying.refusal(error)
                if refused is None:
                    raise
                problem = system_status.Problem(
                    Reason.APPLY_REFUSED, f"The API server refused a write: {refused}"
                )
            # Counts and Ready follow the revision robots are moved to (an earlier one after undo).
            if fleet is not None:
                revision = fleet.target
            if fleet is not None and fleet.failed:
                problem = system_status.Problem(Reason.HEALTH_GATE_FAILED, fleet.status.get("message", ""))
    # Instances stopping because their robot left are no longer part of the system's counts.
    counted = [instance for instance in observed if not instance.spec.get("retiring")]
    view = system_status.SystemView(
        matched=matched,
        instances=counted,
        revision=revision,
        problem=problem,
        rollout=fleet.verdict if fleet is not None else None,
        rolled_back=system_status.describe_rollback(fleet.status if fleet is not None else None),
    )
    new = system_status.build_system_status(
        view, old_conditions=list(status.get("conditions") or []), generation=meta.get("generation"), now=now
    )
    events.on_condition_changes(body, list(status.get("conditions") or []), new["conditions"])
    if fleet is not None:
        new["rollout"] = fleet.status
    for key, value in new.items():
        if status.get(key) != value:
            patch.status[key] = value


def _deploy(
    body: kopf.Body,
    name: str,
    namespace: str,
    uid: str,
    spec: CoralSystemSpec,
    files: tuple[str, str],
    observed: list[Any],
    robot_nodes: kopf.Index,
    status: kopf.Status,
) -> tuple[int, rollouts.FleetPlan]:
    """Make the instances follow the robots and the rollout; returns (matched robots, rollout plan)."""
    tree_cm = configmaps.build_config_map(
        system=name,
        namespace=namespace,
        system_uid=uid,
        kind="tree",
        key=configmaps.TREE_KEY,
        text=files[0],
        beside=spec.tree.files,
    )
    params_cm = configmaps.build_config_map(
        system=name,
        namespace=namespace,
        system_uid=uid,
        kind="params",
        key=configmaps.PARAMS_KEY,
        text=files[1],
    )
    template = instances.build_template(spec, tree_cm["metadata"]["name"], params_cm["metadata"]["name"])
    robots = selection.select_robots(spec.robots, robot_nodes.get(ALL_ROBOTS, []))
    fleet = rollouts.plan_fleet(
        body=body,
        name=name,
        namespace=namespace,
        uid=uid,
        spec=spec,
        template=template,
        robots=robots,
        observed=observed,
        status=status,
        now=datetime.now(UTC),
    )
    reachable = {node.node_name for node in robot_nodes.get(ALL_ROBOTS, []) if node.ready}
    plan = instances.plan_instances(fleet.desired, observed, reachable)
    if plan.empty:
        return len(robots), fleet
    if plan.create:
        # The executors' account before new instances: their pods are admitted only once it exists.
        applying.apply_rbac(rbac.build_executor_rbac(system=name, namespace=namespace, system_uid=uid))
    # ConfigMaps first: an instance must never point at a file that does not exist yet. Named by
    # content, so one already listed is already right: no create that would answer 409.
    existing = applying.list_system_config_maps(namespace, name)
    for manifest in (tree_cm, params_cm):
        if manifest["metadata"]["name"] not in existing:
            applying.create_config_map(manifest)
    _apply_plan(body, namespace, plan)
    in_use = {tree_cm["metadata"]["name"], params_cm["metadata"]["name"], *fleet.in_use}
    for instance in observed:
        in_use.add((instance.spec.get("tree") or {}).get("configMap", ""))
        in_use.add((instance.spec.get("parameters") or {}).get("configMap", ""))
    for stale in configmaps.plan_config_map_cleanup(existing, in_use):
        applying.delete_config_map(namespace, stale)
    return len(robots), fleet
