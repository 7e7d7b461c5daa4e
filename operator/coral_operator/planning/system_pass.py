"""One CoralSystem pass as a pure decision: from what was observed to every write it calls for.

`plan_system` validates the spec and its files, chooses the robots, stores the newest revision in
the history, asks `planning.rollout` which robots move, and builds the CoralInstances that carry
the moves out. It writes nothing and remembers nothing: the reconciler (`reconcile.systems`)
reads the observation, applies the plan through `kube`, and computes status from what it sees.
See docs/architecture.md for where this sits on the data path.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from coral_core import names
from pydantic import ValidationError

from coral_operator.api.rollout import RolloutStatus
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import (
    budgets,
    configmaps,
    effective,
    halting,
    instances,
    policy,
    preflight,
    prepull,
    pull_state,
    rbac,
    revisions,
    rollout,
    selection,
    validation,
)
from coral_operator.planning.observed import ObservedInstance, ObservedPod, RobotNode, SystemRecord
from coral_operator.planning.overrides import ConfigError
from coral_operator.status.conditions import Reason
from coral_operator.status.system_status import Problem

SourceText = tuple[str, str]
"""(file text, the name messages give it: `configmap/NAME/KEY` or the inline field)."""


@dataclass(frozen=True)
class SystemObservation:
    """Everything one system pass decides from, read by the reconciler before planning."""

    system: SystemRecord
    spec: CoralSystemSpec | Problem
    """`system.spec` as parsed once for the pass (`parse_spec`)."""
    tree: SourceText | Problem | None
    """The tree's text; None when the spec did not parse, so nothing was read."""
    parameters: SourceText | Problem | None
    robots: list[RobotNode]
    """Every robot Node (the selector is applied here)."""
    instances: list[ObservedInstance]
    """The system's CoralInstances."""
    stored_revisions: list[revisions.StoredRevision]
    """The system's revision history (ControllerRevisions)."""
    expected: Mapping[str, str]
    """Robot -> revision it was moved to by an earlier pass, not yet seen in `instances`."""
    previous_rollout: RolloutStatus | None
    """`status.rollout` as last written."""
    policy: policy.Policy
    now: datetime
    neighbours: list[budgets.Footprint] = field(default_factory=list)
    """The other CoralSystems of the namespace, for its budget (`planning.budgets`)."""
    verdicts: validation.Verdicts | None = None
    """Validation results already known, by content hash."""
    images: preflight.ImageTable = field(default_factory=preflight.ImageTable)
    """What the images of the spec declare, as read from their registries (`reconcile.declarations`)."""
    coral_version: str = preflight.CORAL_VERSION
    pods: Mapping[str, Sequence[ObservedPod]] | None = None
    """Instance name -> its pods; read only with `spec.rollout.prePull` (the pre-pull pods)."""


@dataclass
class RolloutPlan:
    """What the rollout decided in this pass."""

    status: RolloutStatus
    target: str
    """The revision robots are moved to."""
    moves: dict[str, str]
    """Robot -> revision moved to in this pass."""
    events: list[rollout.RolloutEvent]
    wake_at: datetime | None
    """When to decide again even if nothing changes (a canary hold ends)."""
    pulls: prepull.PullWrites = field(default_factory=prepull.PullWrites)
    """Pre-pull pods to create and delete (`spec.rollout.prePull`)."""


@dataclass
class SystemPlan:
    """The writes of one system pass, in the order they must happen."""

    problem: Problem | None = None
    """Why nothing is deployed (invalid spec, tree or parameters, policy), or None."""
    matched: int = 0
    """Robots the selector matches."""
    history: revisions.HistoryPlan | None = None
    config_maps: list[dict[str, Any]] = field(default_factory=list)
    """The validated tree and parameters; created before any instance points at them."""
    changes: instances.InstanceChanges = field(default_factory=instances.InstanceChanges)
    identity: list[dict[str, Any]] = field(default_factory=list)
    """The executors' ServiceAccount, Role and RoleBinding, when instances are created: their
    executor pods are admitted only once it exists (one per system, narrowed per robot by the
    admission policy of `planning.rbac`)."""
    in_use: set[str] = field(default_factory=set)
    """ConfigMaps some revision or instance still points at (never cleaned up)."""
    rollout: RolloutPlan | None = None
    stored_after: list[revisions.StoredRevision] = field(default_factory=list)
    """The revision history once `history` is applied."""
    config_errors: list[ConfigError] = field(default_factory=list)
    """Robots whose effective configuration (the spec with their overrides) is invalid: they keep
    what they run, and the system names each with the field at fault."""
    preflight_notes: list[str] = field(default_factory=list)
    """Images whose trees preflight left to the robot (they declare nothing, or were not read)."""


def format_validation(error: ValidationError) -> str:
    parts = []
    for item in error.errors():
        where = "spec." + ".".join(str(p) for p in item["loc"]) if item["loc"] else "spec"
        parts.append(f"{where}: {item['msg']}")
    return "; ".join(parts)


def parse_spec(spec: Mapping[str, Any]) -> CoralSystemSpec | Problem:
    try:
        return CoralSystemSpec.model_validate(dict(spec))
    except ValidationError as error:
        return Problem(Reason.INVALID_SPEC, format_validation(error))


def listed(problems: list[str], shown: int = validation.PROBLEMS_SHOWN) -> str:
    """The first problems, then how many more: a tree can have thousands."""
    more = len(problems) - shown
    return "; ".join(problems[:shown]) + (f"; and {more} more problems" if more > 0 else "")


def validate_files(observation: SystemObservation, spec: CoralSystemSpec) -> tuple[str, str] | Problem:
    """Validated (tree text, parameters text), or the problem that stalls the system."""
    tree, params = observation.tree, observation.parameters
    if isinstance(tree, Problem):
        return tree
    if isinstance(params, Problem):
        return params
    assert tree is not None and params is not None  # read whenever the spec parsed
    name, namespace = observation.system.name, observation.system.namespace
    problems = validation.validate_tree(
        tree[0],
        tree[1],
        spec.tree.main_tree_id,
        spec.tree.files,
        files_label=f"coralsystem/{name} spec.tree.files",
        verdicts=observation.verdicts,
    )
    if problems:
        return Problem(Reason.INVALID_TREE, listed(problems))
    problems = validation.validate_parameters(params[0], params[1], observation.verdicts)
    if problems:
        return Problem(Reason.INVALID_PARAMETERS, listed(problems))
    denied = policy.evaluate_policy(namespace, spec, observation.policy)
    if denied:
        return Problem(Reason.POLICY_DENIED, "Refused by the operator's policy: " + listed(denied))
    return tree[0], params[0]


def config_problem(plan: SystemPlan) -> Problem | None:
    """What makes the system Stalled when some robots' effective configurations are invalid (the
    others deploy): each such robot with the field at fault."""
    if not plan.config_errors:
        return None
    return Problem(
        Reason.INVALID_ROBOT_CONFIG,
        f"{len(plan.config_errors)} robots have no valid configuration and keep what they run: "
        + listed([str(error) for error in plan.config_errors], shown=10),
    )


def plan_system(observation: SystemObservation) -> SystemPlan:
    """Decide one pass of a CoralSystem (see the module docstring).

    Raises:
        ValueError: the rollout policy cannot be applied (`maxUnavailable` malformed).
    """
    spec = observation.spec
    if isinstance(spec, Problem):
        return SystemPlan(problem=spec, matched=len(observation.instances))
    try:
        files = validate_files(observation, spec)
    except Exception as error:  # noqa: BLE001 - one system's input must not stop the others
        files = Problem(
            Reason.VALIDATION_FAILED, f"The spec could not be validated ({type(error).__name__})."
        )
    if isinstance(files, Problem):
        return SystemPlan(problem=files, matched=len(observation.instances))
    return _plan_deployment(observation, spec, files)


def _plan_deployment(
    observation: SystemObservation, spec: CoralSystemSpec, files: tuple[str, str]
) -> SystemPlan:
    system = observation.system
    common = {"system": system.name, "namespace": system.namespace, "system_uid": system.uid}
    tree_cm = configmaps.build_config_map(
        **common, kind="tree", key=configmaps.TREE_KEY, text=files[0], beside=spec.tree.files
    )
    params_cm = configmaps.build_config_map(**common, kind="params", key=configmaps.PARAMS_KEY, text=files[1])
    template = effective.with_overrides(
        instances.build_template(spec, tree_cm["metadata"]["name"], params_cm["metadata"]["name"]),
        spec,
        *files,
    )
    revision = instances.revision_of(template)
    robots = selection.select_robots(spec.robots, observation.robots)
    too_large = _check_budgets(observation, len(robots))
    if too_large is not None:
        return SystemPlan(problem=too_large, matched=len(robots))
    observed = observation.instances
    by_robot = {i.robot: i for i in observed if not i.spec.get("retiring")}
    history = revisions.plan_history(
        stored=observation.stored_revisions,
        revision=revision,
        template=template,
        in_use={i.revision for i in observed},
        **common,
    )
    stored = stored_after(observation.stored_revisions, history, revision, template)
    templates = {s.revision: s.template for s in stored}
    for instance in observed:
        # A robot kept on its revision must get back exactly the spec it has, or it would be
        # rewritten (and counted unavailable) for nothing; the stored template is that spec. Only
        # where none is stored is the instance's own spec the template, and only an instance this
        # system controls: one written or edited by hand must not become a revision of it.
        if instance.revision != revision and instance.controller_uid == system.uid:
            templates.setdefault(instance.revision, revisions.template_of_instance(instance.spec))
    resolver = effective.EffectiveTemplates(**common, verdicts=observation.verdicts)
    wanted = {robot.robot: resolver.resolve(template, robot) for robot in robots}
    errors = {name: w for name, w in wanted.items() if isinstance(w, ConfigError)}
    checked = preflight.check_robots(
        wanted,
        preflight.tree_sources(
            [tree_cm, *resolver.config_maps.values()],
            tree_cm["metadata"]["name"],
            observation.tree[1] if isinstance(observation.tree, tuple) else "tree",
            f"coralsystem/{system.name}",
        ),
        observation.images,
        observation.coral_version,
        observation.verdicts,
    )
    if checked.problems:
        # Refused before the rollout: no instance is created or moved, every robot keeps what it runs.
        return SystemPlan(
            problem=Problem(
                Reason.PREFLIGHT_FAILED,
                "Preflight refused the change; no robot moves: " + listed(checked.problems, shown=10),
            ),
            matched=len(robots),
            preflight_notes=checked.notes,
        )
    # A robot whose configuration the new revision leaves as it is moves to it at once, costing no
    # budget and restarting nothing: a change to one model's override rolls out to that model only.
    unchanged = {
        name
        for name, instance in by_robot.items()
        if instance.revision != revision
        and name in wanted
        and name not in errors
        and instance.spec.get(effective.CONFIG_HASH) == wanted[name][effective.CONFIG_HASH]  # type: ignore[index]
    }
    # Moved so by an earlier pass, not yet in the index: written already, and as available as before.
    moving = {name for name in unchanged if observation.expected.get(name) != revision}
    decision = rollout.plan_rollout(
        rollout.RolloutRequest(
            desired=revision,
            history=history.order,
            robots=_views(
                spec,
                [r for r in robots if r.robot not in errors],
                by_robot,
                observation.expected,
                {name: revision for name in unchanged},
                observation.pods,
            ),
            policy=spec.rollout,
            previous=observation.previous_rollout,
            now=observation.now,
            undo_from=system.annotations.get(names.ANNOTATION_ROLLOUT_UNDO),
            resumed=system.annotations.get(names.ANNOTATION_ROLLOUT_RESUME),
        )
    )
    builder = instances.InstanceBuilder(system=system.name, namespace=system.namespace, system_uid=system.uid)
    desired = []
    for robot in robots:
        instance = by_robot.get(robot.robot)
        if robot.robot in moving and decision.target == revision:
            chosen = revision
        else:
            chosen = decision.moves.get(robot.robot) or (
                instance.revision if instance is not None else decision.create_revision
            )
        if chosen not in templates:
            chosen = revision
        resolved = wanted[robot.robot] if chosen == revision else resolver.resolve(templates[chosen], robot)
        if isinstance(resolved, ConfigError):
            errors.setdefault(robot.robot, resolved)
            if instance is not None:
                desired.append(builder.keep(robot, instance.spec))
            continue
        manifest = builder.build(robot, resolved)
        manifest["spec"]["revision"] = chosen
        halt = halting.halt_of_robot(spec.halt, robot.robot)
        if halt is not None:
            manifest["spec"]["halt"] = halt
        desired.append(manifest)
    reachable = {node.node_name for node in observation.robots if node.ready}
    in_use = {tree_cm["metadata"]["name"], params_cm["metadata"]["name"]}
    for kept in [*templates.values(), *(i.spec for i in observed), *(m["spec"] for m in desired)]:
        in_use.add((kept.get("tree") or {}).get("configMap", ""))
        in_use.add((kept.get("parameters") or {}).get("configMap", ""))
    changes = instances.plan_instances(desired, observed, reachable, builder.shared_keys, system.uid)
    identity = (
        rbac.build_executor_rbac(system=system.name, namespace=system.namespace, system_uid=system.uid)
        if changes.create
        else []
    )
    return SystemPlan(
        matched=len(robots),
        history=history,
        config_maps=[tree_cm, params_cm, *resolver.config_maps.values()],
        changes=changes,
        identity=identity,
        in_use=in_use,
        rollout=RolloutPlan(
            status=decision.status,
            target=decision.target,
            moves={
                **({name: revision for name in moving} if decision.target == revision else {}),
                **decision.moves,
            },
            events=list(decision.events),
            wake_at=decision.wake_at,
            pulls=_plan_pulls(observation, decision, by_robot, templates, robots),
        ),
        stored_after=stored,
        config_errors=[errors[name] for name in sorted(errors)],
        preflight_notes=checked.notes,
    )


def _check_budgets(observation: SystemObservation, robots: int) -> Problem | None:
    """Why the system's copies on its robots, or its namespace's total, are refused; checked
    before any instance is built, so a refused system costs no more than its own record."""
    system = observation.system
    refused = budgets.check_expansion(system.share_bytes, robots)
    if refused is None:
        own = budgets.Footprint(system.name, system.created, system.spec_bytes, system.share_bytes, robots)
        refused = budgets.check_namespace(system.namespace, own, observation.neighbours)
    return None if refused is None else Problem(Reason.TOO_LARGE, refused)


def stored_after(
    stored: list[revisions.StoredRevision],
    plan: revisions.HistoryPlan,
    revision: str,
    template: dict[str, Any],
) -> list[revisions.StoredRevision]:
    """The revision history as it is once `plan` is applied."""
    by_revision = {s.revision: s for s in stored}
    if plan.create is not None:
        by_revision[revision] = revisions.StoredRevision(
            plan.create["metadata"]["name"], revision, plan.create["revision"], template
        )
    if plan.renumber is not None:
        old = by_revision[revision]
        by_revision[revision] = revisions.StoredRevision(old.name, revision, plan.renumber[1], old.template)
    deleted = set(plan.delete)
    return [s for s in by_revision.values() if s.name not in deleted]


def _plan_pulls(
    observation: SystemObservation,
    decision: rollout.RolloutDecision,
    by_robot: Mapping[str, ObservedInstance],
    templates: Mapping[str, dict[str, Any]],
    robots: list[RobotNode],
) -> prepull.PullWrites:
    if observation.pods is None:
        return prepull.PullWrites()
    nodes = {robot.robot: robot.node_name for robot in robots}
    images = prepull.revision_images(templates.get(decision.target, {}))
    wanted = [
        prepull.PullTarget(
            instance=by_robot[robot].name,
            instance_uid=by_robot[robot].uid,
            node_name=nodes[robot],
            robot=robot,
            images=images,
        )
        for robot in decision.pulls
        if robot in by_robot and robot in nodes and by_robot[robot].uid
    ]
    return prepull.plan_pulls(
        system=observation.system.name,
        namespace=observation.system.namespace,
        target=decision.target,
        wanted=wanted,
        pods=observation.pods,
    )


def _views(
    spec: CoralSystemSpec,
    robots: list[RobotNode],
    by_robot: Mapping[str, ObservedInstance],
    expected: Mapping[str, str],
    moved_free: Mapping[str, str],
    pods: Mapping[str, Sequence[ObservedPod]] | None = None,
) -> list[rollout.RobotView]:
    canary = spec.rollout.canary
    views = []
    for robot in robots:
        instance = by_robot.get(robot.robot)
        revision = moved_free.get(robot.robot) or (instance.revision if instance else None)
        ready = bool(instance and instance.ready)
        if robot.robot in expected and expected[robot.robot] != revision:
            # Moved by an earlier pass, not yet in the index: it is on its way and unavailable.
            revision, ready = expected[robot.robot], False
        views.append(
            rollout.RobotView(
                robot=robot.robot,
                revision=revision,
                ready=ready,
                online=robot.ready,
                root_status=instance.root_status if instance else None,
                stalled=bool(instance and instance.stalled),
                canary=canary is not None and selection.matches(canary.robots, robot.labels),
                pulls=pull_state.read_pulls(pods.get(instance.name, ())) if pods and instance else {},
            )
        )
    return views
