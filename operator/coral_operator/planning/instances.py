"""From a CoralSystem and its matched robots to the CoralInstances that should exist.

`build_instance_spec` freezes one revision of the system for one robot; `plan_instances` compares
desired and existing instances. Pure; called by `planning.system_pass`. Fleet rollouts (which
instances move to a new revision, and when) plug in between the two without changing them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from coral_core import names
from coral_core.names import API_VERSION

from coral_operator.api.instance import ConfigRef, CoralInstanceSpec, InstanceTree
from coral_operator.api.offline import InstanceOffline
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import naming
from coral_operator.planning.observed import ROBOT_SPEC_FIELDS, ObservedInstance, RobotNode, shared_spec_key


def build_template(spec: CoralSystemSpec, tree_config_map: str, params_config_map: str) -> dict[str, Any]:
    """What every robot of the revision runs, without the robot-specific fields (wire format)."""
    return {
        "ros": spec.ros.to_wire(),
        "parameters": ConfigRef(config_map=params_config_map).to_wire(),
        "tree": InstanceTree(
            config_map=tree_config_map,
            main_tree_id=spec.tree.main_tree_id,
            tick_rate_hz=spec.tree.tick_rate_hz,
            # Unset unless given (`to_wire` drops it): older revisions keep their hash.
            no_progress_seconds=spec.tree.no_progress_seconds,
        ).to_wire(),
        "drivers": [c.to_wire() for c in spec.drivers],
        "skillsets": [c.to_wire() for c in spec.skillsets],
        "executors": [c.to_wire() for c in spec.executors],
        "startup": spec.startup.to_wire(),
        "plugins": spec.plugins.to_wire(),
        # Only when not the default, so the revisions of systems written before layouts existed
        # stay the same and an operator upgrade restarts no robot.
        **({"layout": spec.layout} if spec.layout != "PodPerComponent" else {}),
        # Likewise only when on: systems that leave it off keep their revision.
        **(
            {
                "offline": InstanceOffline(
                    interrupt_running_trees=spec.rollout.interrupt_running_trees
                ).to_wire()
            }
            if spec.offline.mode != "Off"
            else {}
        ),
    }


def revision_of(template: dict[str, Any]) -> str:
    """The revision hash of a template; equal templates give equal revisions."""
    return naming.content_hash(template)


def build_instance_spec(system: str, robot: RobotNode, template: dict[str, Any]) -> dict[str, Any]:
    """The CoralInstance spec of one robot at the template's revision (validated by the model)."""
    wire = {
        "system": system,
        "robot": robot.robot,
        "nodeName": robot.node_name,
        "revision": revision_of(template),
        **template,
    }
    return CoralInstanceSpec.model_validate(wire).to_wire()


class InstanceBuilder:
    """Builds the CoralInstance manifests of one system for one pass.

    Every robot at a revision gets the same spec but for its robot fields, so each template is
    validated once and the robots' specs are copies of it: a fleet pass builds a thousand
    instances, and validating each one was most of the pass.
    """

    def __init__(self, *, system: str, namespace: str, system_uid: str) -> None:
        self.system = system
        self.namespace = namespace
        self.owner = naming.owner_reference(API_VERSION, names.SYSTEM_KIND, system, system_uid)
        # Keyed by the template object, which the entry keeps alive so its id is not reused.
        self._specs: dict[int, tuple[dict[str, Any], dict[str, Any], str]] = {}
        self.shared_keys: dict[str, str] = {}
        """Instance name -> `observed.shared_spec_key` of its spec, for `plan_instances`."""

    def _spec(self, robot: RobotNode, template: dict[str, Any]) -> tuple[dict[str, Any], str]:
        known = self._specs.get(id(template))
        if known is None:
            spec = build_instance_spec(self.system, robot, template)
            known = (template, spec, shared_spec_key(spec))
            self._specs[id(template)] = known
        return {**known[1], "robot": robot.robot, "nodeName": robot.node_name}, known[2]

    def keep(self, robot: RobotNode, spec: dict[str, Any]) -> dict[str, Any]:
        """The manifest of `robot`'s instance with the spec it has: a robot whose configuration
        cannot be resolved keeps what it runs."""
        return self._manifest(robot, spec)

    def build(self, robot: RobotNode, template: dict[str, Any]) -> dict[str, Any]:
        """The full CoralInstance manifest of `robot` at `template`'s revision."""
        spec, key = self._spec(robot, template)
        self.shared_keys[naming.instance_name(self.system, robot.robot)] = key
        return self._manifest(robot, spec)

    def _manifest(self, robot: RobotNode, spec: dict[str, Any]) -> dict[str, Any]:
        name = naming.instance_name(self.system, robot.robot)
        return {
            "apiVersion": API_VERSION,
            "kind": names.INSTANCE_KIND,
            "metadata": {
                "name": name,
                "namespace": self.namespace,
                "labels": naming.instance_labels(self.system, robot.robot),
                "ownerReferences": [self.owner],
            },
            "spec": spec,
        }


def build_instance(
    *,
    system: str,
    namespace: str,
    system_uid: str,
    robot: RobotNode,
    template: dict[str, Any],
) -> dict[str, Any]:
    """The full CoralInstance manifest, owned by its CoralSystem."""
    return InstanceBuilder(system=system, namespace=namespace, system_uid=system_uid).build(robot, template)


@dataclass
class InstanceChanges:
    """What to do with a system's CoralInstances; each list holds manifests or names."""

    create: list[dict[str, Any]] = field(default_factory=list)
    update: list[dict[str, Any]] = field(default_factory=list)
    retire: list[str] = field(default_factory=list)
    """Instances whose robot left the selector but is reachable: they stop in reverse order first."""
    delete: list[str] = field(default_factory=list)
    """Instances to delete now (their robot is gone or unreachable, so nothing could stop in order)."""

    @property
    def empty(self) -> bool:
        return not (self.create or self.update or self.retire or self.delete)


def _normalized(spec: dict[str, Any]) -> dict[str, Any] | None:
    # The API server stores defaults and may render 10.0 as 10; compare model to model.
    try:
        return CoralInstanceSpec.model_validate(spec).to_wire()
    except ValueError:
        return None


def _same_spec(current: ObservedInstance, spec: dict[str, Any], shared_key: str | None) -> bool:
    if shared_key is not None and current.shared_spec_key == shared_key:
        return all(current.spec.get(key) == spec.get(key) for key in ROBOT_SPEC_FIELDS)
    # Equal as stored is the common case; only a difference is worth validating.
    return current.spec == spec or _normalized(current.spec) == spec


def _controller_uid(manifest: dict[str, Any]) -> str:
    return str(manifest["metadata"]["ownerReferences"][0]["uid"])


def plan_instances(
    desired: list[dict[str, Any]],
    existing: list[ObservedInstance],
    reachable_nodes: set[str] | None = None,
    shared_keys: dict[str, str] | None = None,
    system_uid: str | None = None,
) -> InstanceChanges:
    """Create the missing, update the changed, retire or delete those whose robot left the selector.

    Args:
        desired: instance manifests for the matched robots.
        existing: the system's instances as observed.
        reachable_nodes: Nodes that are Ready; a leaving robot among them is retired (its
            components stop executors first, drivers last), any other is deleted at once.
        shared_keys: instance name -> `observed.shared_spec_key` of its desired spec
            (`InstanceBuilder.shared_keys`); where the observed one has the same, only the robot's
            own fields are compared. Without it, whole specs are.
        system_uid: the system's uid; a leaving instance it does not control (written by hand
            at one of its names) is deleted at once, as it would never stop in order.
    """
    shared_keys = shared_keys or {}
    plan = InstanceChanges()
    by_name = {instance.name: instance for instance in existing}
    wanted = set()
    for manifest in desired:
        name = manifest["metadata"]["name"]
        wanted.add(name)
        current = by_name.get(name)
        if current is None:
            plan.create.append(manifest)
        elif (
            current.labels != manifest["metadata"]["labels"]
            or current.controller_uid != _controller_uid(manifest)
            or not _same_spec(current, manifest["spec"], shared_keys.get(name))
        ):
            # Also one written by hand at a name of the system's: the system takes it over (spec,
            # labels, owner), as the instance reconciler serves no instance its system does not own.
            plan.update.append(manifest)
    for name in sorted(set(by_name) - wanted):
        instance = by_name[name]
        controlled = system_uid is None or instance.controller_uid == system_uid
        if controlled and instance.spec.get("nodeName") in (reachable_nodes or set()):
            if not instance.spec.get("retiring"):
                plan.retire.append(name)
        else:
            plan.delete.append(name)
    return plan
