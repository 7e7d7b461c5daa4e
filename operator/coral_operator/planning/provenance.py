"""Whether a CoralInstance is the operator's own: made by a system pass for a system that still wants it.

CoralInstances are an internal object, like a Deployment's ReplicaSets, yet anyone with `create` on
them could write one by hand, and the instance reconciler used to build pods from whatever it
found: a privileged, host-network pod with `/` mounted, for a user who may not create pods, or a
pod running as another system's executor account (issue 47, item 6). So a pass builds pods only
for an instance that

- names (`spec.system`) a CoralSystem of its namespace, which is its controller owner by uid;
- is named as the system pass names the instance of (system, robot);
- is pinned to the Node of that robot;
- has a spec equal to one the system's stored revisions (`planning.revisions`) give that robot;
- asks for nothing the operator's policy refuses in its namespace (`planning.policy`), which
  holds even for the system's own revisions after an administrator narrowed the policy.

Anything else is left alone with its reasons on its status and an Event (`reconcile.instances`):
no pod is built, none is deleted (docs/architecture.md, "Who may write a CoralInstance"). Pure.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from coral_core import names
from pydantic import ValidationError

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.planning import effective, naming, policy, validation
from coral_operator.planning.observed import ObservedInstance, RobotNode, SystemRecord
from coral_operator.planning.overrides import ConfigError
from coral_operator.planning.revisions import StoredRevision, template_of_instance


def controller_of(owners: Iterable[Any]) -> Mapping[str, Any] | None:
    """The owner reference marked `controller`, if there is one."""
    for owner in owners:
        if isinstance(owner, Mapping) and owner.get("controller") is True:
            return owner
    return None


def is_claimed_by(instance: ObservedInstance, system: str, system_uid: str) -> bool:
    """Whether a system pass plans with `instance`: one the system controls, or one at a name the
    system gives, which it takes over (spec, labels, owner). Any other instance naming the system
    is not counted, moved or deleted by it: its own pass serves it no pod."""
    return instance.controller_uid == system_uid or instance.name == naming.instance_name(
        system, instance.robot
    )


def evaluate_ownership(
    *,
    name: str,
    owners: Iterable[Any],
    spec: CoralInstanceSpec,
    system: SystemRecord | None,
    node: RobotNode | None,
) -> list[str]:
    """Every way the instance is not one its system made for its robot; empty if it is.

    Args:
        name: the instance's name.
        owners: its `metadata.ownerReferences`.
        spec: its parsed spec.
        system: the CoralSystem of its namespace named by `spec.system`, None if none exists.
        node: the robot Node named by `spec.nodeName`, None if no robot Node has that name (the
            reconciler then builds no pod, whoever made the instance).
    """
    if system is None:
        return [f"spec.system: no CoralSystem {spec.system} exists in this namespace"]
    problems = []
    controller = controller_of(owners)
    if controller is None:
        problems.append(f"metadata.ownerReferences: no controller; CoralSystem {system.name} must be it")
    elif (
        str(controller.get("apiVersion", "")).split("/")[0] != names.GROUP
        or controller.get("kind") != names.SYSTEM_KIND
        or controller.get("name") != system.name
        or controller.get("uid") != system.uid
    ):
        problems.append(
            f"metadata.ownerReferences: the controller is {controller.get('kind')} "
            f"{controller.get('name')} (uid {controller.get('uid')}), not CoralSystem {system.name} "
            f"(uid {system.uid})"
        )
    expected = naming.instance_name(spec.system, spec.robot)
    if name != expected:
        problems.append(f"metadata.name: the instance of robot {spec.robot} in {spec.system} is {expected}")
    # No Node at all is the robot's own trouble (NodeMissing); no pod is built for it either.
    if node is not None and node.robot != spec.robot:
        problems.append(f"spec.nodeName: Node {spec.node_name} is robot {node.robot}, not {spec.robot}")
    return problems


def evaluate_revision(
    spec: CoralInstanceSpec,
    stored: list[StoredRevision],
    node: RobotNode | None = None,
    system: SystemRecord | None = None,
    verdicts: validation.Verdicts | None = None,
) -> str | None:
    """Why the spec is not what its system's revision `spec.revision` gives its robot; None if it is.

    `stored` is the system's revision history; a revision no robot runs any more may have been
    pruned from it, and an instance still asking for it is not served. A revision with overrides
    is resolved for the robot's Node (`planning.effective`), as the system pass resolved it.
    """
    revision = next((s for s in stored if s.revision == spec.revision), None)
    if revision is None:
        return f"spec.revision: {spec.revision} is no stored revision of CoralSystem {spec.system}"
    robot_fields = {
        "system": spec.system,
        "robot": spec.robot,
        "nodeName": spec.node_name,
        "revision": spec.revision,
    }
    resolver = effective.EffectiveTemplates(
        system=spec.system,
        namespace=system.namespace if system else "",
        system_uid=system.uid if system else "",
        verdicts=verdicts,
    )
    robot = node or RobotNode(node_name=spec.node_name, robot=spec.robot, labels={}, ready=False)
    try:
        template = resolver.resolve(revision.template, robot)
        if isinstance(template, ConfigError):
            return (
                f"spec.revision: revision {spec.revision} gives this robot no valid configuration: {template}"
            )
        wanted = CoralInstanceSpec.model_validate({**template, **robot_fields}).to_wire()
    except (ValidationError, TypeError, KeyError):
        return f"spec.revision: the stored revision {spec.revision} cannot be read"
    # The hash only names the rest, and instances written before it existed lack it.
    if _without_hash(wanted) != _without_hash(spec.to_wire()):
        return f"spec: differs from revision {spec.revision} of CoralSystem {spec.system}"
    return None


def _without_hash(spec: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in template_of_instance(spec).items() if k != effective.CONFIG_HASH}


def evaluate_instance_policy(namespace: str, spec: CoralInstanceSpec, rules: policy.Policy) -> list[str]:
    """The privilege policy over what the instance's pods would be built from."""
    return policy.evaluate_policy(namespace, spec, rules)
