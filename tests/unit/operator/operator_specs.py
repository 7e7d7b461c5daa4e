"""Small, valid CoralSystem specs and observed robots shared by the operator's unit tests."""

from __future__ import annotations

import copy
from datetime import UTC, datetime
from typing import Any

from coral_core import names
from coral_core.instance_status import PluginState, TreeState
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec, StartupSpec
from coral_operator.kube import observing
from coral_operator.planning import instances, pods, preflight, system_pass
from coral_operator.planning import startup as startup_planning
from coral_operator.planning.observed import ObservedInstance, ObservedPod, RobotNode
from coral_operator.status import executor_report, instance_status
from fixtures.system_passes import plan_system_pass

TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <AlwaysSuccess/>
    </Sequence>
  </BehaviorTree>
</root>
"""

BASE_SPEC: dict[str, Any] = {
    "robots": {"matchLabels": {"fleet": "a"}},
    "parameters": {"inline": "driver:\n  ros__parameters:\n    rate: 10\n"},
    "tree": {"inline": TREE},
    "drivers": [{"name": "lidar", "image": "example/lidar:1"}],
    "skillsets": [{"name": "slam", "image": "example/slam:1"}],
    "executors": [{"name": "executor", "image": "example/executor:1"}],
}

NOW = datetime(2026, 1, 1, 12, 0, 0, tzinfo=UTC)


def robot(name: str, ready: bool = True, **labels: str) -> RobotNode:
    return RobotNode(
        node_name=name,
        robot=name,
        labels={"coral.dev/robot": name, "fleet": "a", **labels},
        ready=ready,
        last_seen=NOW,
        reachable=ready,
    )


def observed_instance(manifest: dict[str, Any], ready: bool = False) -> ObservedInstance:
    """The instance as the system wrote it from `manifest` (owned by the system)."""
    return ObservedInstance(
        name=manifest["metadata"]["name"],
        robot=manifest["spec"]["robot"],
        spec=copy.deepcopy(manifest["spec"]),
        revision=manifest["spec"]["revision"],
        labels=manifest["metadata"]["labels"],
        controller_uid=manifest["metadata"]["ownerReferences"][0]["uid"],
        ready=ready,
    )


def instance_view(
    spec: CoralInstanceSpec,
    desired: list[dict[str, Any]],
    observed: list[ObservedPod],
    *,
    startup: StartupSpec,
    node: RobotNode | None = None,
    tree: dict[str, Any] | TreeState | None = None,
    plugins: dict[str, Any] | PluginState | None = None,
    refused: dict[str, str] | None = None,
) -> instance_status.InstanceView:
    """What an instance's status is computed from, on robot r1 unless `node` says otherwise, with
    its start-up planned at NOW as the reconciler plans it. `tree` and `plugins` as the executor
    wrote them (read as the reconciler reads them) or as read already."""
    if isinstance(tree, dict) or isinstance(plugins, dict):
        written = (("tree", tree), ("plugins", plugins))
        wire = {key: value for key, value in written if isinstance(value, dict)}
        report = executor_report.read_executor_report(wire)
        tree = report.tree if isinstance(tree, dict) else tree
        plugins = report.plugins if isinstance(plugins, dict) else plugins
    plan = startup_planning.plan_startup(
        desired=desired, observed=observed, transient=set(), startup=startup, now=NOW
    )
    return instance_status.InstanceView(
        spec=spec,
        node=node or robot("r1"),
        desired=desired,
        pods=observed,
        plan=plan,
        transient=set(),
        tree=tree,
        plugins=plugins,
        refused=refused or {},
    )


def view_with_pods_running(
    spec: dict[str, Any],
    *,
    ready: bool = True,
    node_ready: bool = True,
    tree: dict[str, Any] | TreeState | None = None,
    plugins: dict[str, Any] | PluginState | None = None,
) -> instance_status.InstanceView:
    """The instance of system `sys` with `spec` on robot r1, every component's pod Running (Ready or
    not), and the executor's report `tree` and `plugins`."""
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    parsed = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    desired = pods.build_pods(spec=parsed, instance="sys-r1", namespace="ns", instance_uid="u")
    observed = [
        ObservedPod(
            name=m["metadata"]["name"],
            component=m["metadata"]["labels"][names.LABEL_COMPONENT],
            role=m["metadata"]["labels"][names.LABEL_ROLE],
            revision=m["metadata"]["labels"][names.LABEL_REVISION],
            pod_hash=m["metadata"]["annotations"][names.ANNOTATION_POD_HASH],
            phase="Running",
            ready=ready,
            created=NOW,
        )
        for m in desired
    ]
    return instance_view(
        parsed,
        desired,
        observed,
        startup=StartupSpec(),
        node=robot("r1", ready=node_ready),
        tree=tree,
        plugins=plugins,
    )


def plan_pass(
    spec: dict[str, Any],
    robots: list[RobotNode],
    instances: list[ObservedInstance] | None = None,
    stored: list[Any] | None = None,
    name: str = "site",
    annotations: dict[str, str] | None = None,
    expected: dict[str, str] | None = None,
    previous_rollout: Any = None,
    images: preflight.ImageTable | None = None,
) -> system_pass.SystemPlan:
    """One system pass of `spec` (inline files) over `robots`, with a policy that allows the host
    network and nothing else."""
    metadata = {
        "name": name,
        "namespace": "ns",
        "uid": f"u-{name}",
        "generation": 1,
        "annotations": annotations,
    }
    return plan_system_pass(
        observing.system_record({"metadata": metadata, "spec": spec}),
        spec,
        robots,
        now=NOW,
        instances=instances,
        stored=stored,
        expected=expected,
        previous_rollout=previous_rollout,
        images=images,
    )
