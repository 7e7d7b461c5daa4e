"""Fleet rollouts inside the system reconciler: which revision each robot's CoralInstance gets.

Called by `handlers.systems` once per pass, between building the newest template and planning the
instances. It keeps two small in-memory records, both rebuilt from the API after a restart:
the revision history of each system (ControllerRevisions, listed once per system and process) and
the moves made but not yet seen in the instance index ("expectations", as Kubernetes' own
controllers keep them), so a pass that runs before the index caught up never moves more robots
than `maxUnavailable` allows. The decision itself is `planning.rollout.plan_rollout`.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import kopf
from pydantic import ValidationError

from coral_operator.api import keys, names
from coral_operator.api.rollout import RolloutStatus
from coral_operator.api.system import CoralSystemSpec
from coral_operator.handlers import triggers
from coral_operator.kube import revisions as stored_revisions
from coral_operator.planning import instances, revisions, rollout, selection
from coral_operator.planning.observed import ObservedInstance, RobotNode
from coral_operator.status.rollout import evaluate_rollout
from coral_operator.status.transitions import Verdict

# A move not seen in the index after this long is forgotten (the write failed or was replaced).
_EXPECTATION_SECONDS = 60.0

_lock = threading.Lock()
_history: dict[tuple[str, str, str], dict[str, revisions.StoredRevision]] = {}
_expected: dict[tuple[str, str, str], tuple[str, float]] = {}
_wakeups: set[tuple[str, str, str]] = set()
# The rollout status this process wrote last, per system uid: kopf may hand a pass a body read
# before the previous pass's status write landed, and the canary clock or a recorded failure must
# not be lost to that.
_written: dict[str, RolloutStatus] = {}


@dataclass
class FleetPlan:
    """The instances to converge to, and what to report."""

    desired: list[dict[str, Any]]
    status: dict[str, Any]
    """`status.rollout` (wire format)."""
    verdict: Verdict
    """The `RolloutComplete` condition."""
    target: str
    """The revision robots are moved to."""
    in_use: set[str]
    """ConfigMaps referenced by any revision in the history (never cleaned up)."""
    failed: bool


def _history_for(
    namespace: str, system: str, uid: str, revision: str, template: dict[str, Any], in_use: set[str]
) -> tuple[list[str], dict[str, dict[str, Any]]]:
    key = (namespace, system, uid)
    with _lock:
        cached = _history.get(key)
    if cached is None:
        cached = {s.revision: s for s in stored_revisions.read_revisions(namespace, system)}
    plan = revisions.plan_history(
        stored=list(cached.values()),
        system=system,
        namespace=namespace,
        system_uid=uid,
        revision=revision,
        template=template,
        in_use=in_use,
    )
    if plan.create is not None:
        stored_revisions.create_revision(plan.create)
        cached[revision] = revisions.StoredRevision(
            plan.create["metadata"]["name"], revision, plan.create["revision"], template
        )
    if plan.renumber is not None:
        stored_revisions.renumber_revision(namespace, *plan.renumber)
        old = cached[revision]
        cached[revision] = revisions.StoredRevision(old.name, revision, plan.renumber[1], old.template)
    for name in plan.delete:
        stored_revisions.delete_revision(namespace, name)
        cached = {r: s for r, s in cached.items() if s.name != name}
    with _lock:
        _history[key] = cached
    return plan.order, {r: s.template for r, s in cached.items()}


def _views(
    namespace: str,
    uid: str,
    spec: CoralSystemSpec,
    robots: list[RobotNode],
    by_robot: dict[str, ObservedInstance],
) -> list[rollout.RobotView]:
    now = time.monotonic()
    canary = spec.rollout.canary
    views = []
    for robot in robots:
        instance = by_robot.get(robot.robot)
        revision = instance.revision if instance else None
        ready = bool(instance and instance.ready)
        key = (namespace, uid, robot.robot)
        with _lock:
            expected = _expected.get(key)
            if expected is not None and (expected[0] == revision or now - expected[1] > _EXPECTATION_SECONDS):
                del _expected[key]
                expected = None
        if expected is not None:
            # Moved by an earlier pass, not yet in the index: it is on its way and unavailable.
            revision, ready = expected[0], False
        views.append(
            rollout.RobotView(
                robot=robot.robot,
                revision=revision,
                ready=ready,
                online=robot.ready,
                root_status=instance.root_status if instance else None,
                stalled=bool(getattr(instance, "stalled", False)),
                canary=canary is not None and selection.matches(canary.robots, robot.labels),
            )
        )
    return views


def _previous(uid: str, status: kopf.Status) -> RolloutStatus | None:
    with _lock:
        written = _written.get(uid)
    if written is not None:
        return written
    try:
        written = status.get(keys.SYSTEM_STATUS.rollout)
        return RolloutStatus.model_validate(written) if written else None
    except ValidationError:
        return None


def plan_fleet(
    *,
    body: kopf.Body,
    name: str,
    namespace: str,
    uid: str,
    spec: CoralSystemSpec,
    template: dict[str, Any],
    robots: list[RobotNode],
    observed: list[ObservedInstance],
    status: kopf.Status,
    now: datetime,
) -> FleetPlan:
    """Decide this pass of the rollout and the instance manifests that carry it out."""
    revision = instances.revision_of(template)
    annotations = body.get("metadata", {}).get("annotations") or {}
    by_robot = {i.robot: i for i in observed if not i.spec.get("retiring")}
    running = {i.revision for i in observed}
    order, templates = _history_for(namespace, name, uid, revision, template, running)
    for instance in observed:
        # A robot kept on its revision must get back exactly the spec it has, or it would be
        # rewritten (and counted unavailable) for nothing: its own spec is the surest template.
        if instance.revision != revision:
            templates[instance.revision] = revisions.template_of_instance(instance.spec)
    decision = rollout.plan_rollout(
        rollout.RolloutRequest(
            desired=revision,
            history=order,
            robots=_views(namespace, uid, spec, robots, by_robot),
            policy=spec.rollout,
            previous=_previous(uid, status),
            now=now,
            undo_from=annotations.get(names.ANNOTATION_ROLLOUT_UNDO),
            resumed=annotations.get(names.ANNOTATION_ROLLOUT_RESUME),
        )
    )
    with _lock:
        _written[uid] = decision.status
    desired = []
    builder = instances.InstanceBuilder(system=name, namespace=namespace, system_uid=uid)
    started = time.monotonic()
    for robot in robots:
        instance = by_robot.get(robot.robot)
        chosen = decision.moves.get(robot.robot) or (
            instance.revision if instance is not None else decision.create_revision
        )
        if chosen not in templates:
            chosen = revision
        manifest = builder.build(robot, templates[chosen])
        manifest["spec"]["revision"] = chosen
        desired.append(manifest)
        if robot.robot in decision.moves:
            with _lock:
                _expected[(namespace, uid, robot.robot)] = (chosen, started)
    for event in decision.events:
        kopf.event(
            body, type="Warning" if event.warning else "Normal", reason=event.reason, message=event.message
        )
    if decision.wake_at is not None:
        _wake_system_at(namespace, name, decision.wake_at, now)
    in_use = set()
    for kept in templates.values():
        in_use.add((kept.get("tree") or {}).get("configMap", ""))
        in_use.add((kept.get("parameters") or {}).get("configMap", ""))
    wire = decision.status.to_wire()
    for key in (keys.ROLLOUT.failure, keys.ROLLOUT.rolled_back, keys.ROLLOUT.canary):
        # Status is merge-patched: a field that went away must be written as null to be removed.
        if key not in wire and key in (status.get(keys.SYSTEM_STATUS.rollout) or {}):
            wire[key] = None
    return FleetPlan(
        desired=desired,
        status=wire,
        verdict=evaluate_rollout(decision.status),
        target=decision.target,
        in_use=in_use,
        failed=decision.status.failure is not None,
    )


def _wake_system_at(namespace: str, name: str, when: datetime, now: datetime) -> None:
    """Reconcile the system again when the canary hold ends, even if nothing else changes."""
    key = (namespace, name, when.isoformat())
    with _lock:
        if key in _wakeups:
            return
        _wakeups.add(key)
    delay = max((when - now).total_seconds(), 0.0) + 0.5
    timer = threading.Timer(delay, triggers.poke, args=("coralsystems", namespace, name, f"clock-{key[2]}"))
    timer.daemon = True
    timer.start()
