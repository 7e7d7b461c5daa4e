"""What the kind tests of this folder share: the cluster's name, its robots, its handle, and a
mission on one robot read as a user would."""

from __future__ import annotations

import os
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from coral_testbed.cluster import operatorchart
from coral_testbed.cluster.client import Cluster
from coral_testbed.images import catalog
from coral_testbed.kind import clusters, faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.missions import manifests, prepull
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from missions import realsystems as rs

NAME = os.environ.get("CORAL_KIND_TEST_NAME", "coral-test")
"""The kind cluster's name: `CORAL_KIND_TEST_NAME` gives each checkout on one machine its own."""
FLEET_LABEL = {"coral.dev/model": "kind"}
"""What every robot of the cluster carries: a CoralSystem selecting it runs on the whole fleet."""
ROBOTS = {name: dict(FLEET_LABEL) for name in manifests.RELAY_ROBOTS}
"""The relay example's three robots; the other tests use them too."""
MISSIONS_NAMESPACE = "kind-missions"
"""Where `kind_missions`' operator serves the tests' CoralSystems."""


@dataclass(frozen=True)
class KindCluster:
    running: clusters.Running
    cluster: Cluster
    """kubectl, helm and the API client against the kind cluster."""
    share: Path
    """The host folder bound at the site share's path into every robot's node."""


def ready(core: k8s.CoreV1Api, node: str) -> str:
    """The Node's Ready status: True, False or Unknown (its kubelet not heard from)."""
    conditions = core.read_node(node).status.conditions or []
    return next((c.status for c in conditions if c.type == "Ready"), "")


class Mission:
    """One CoralSystem of `realsystems` on `robot`, in the namespace `missions`' operator serves,
    read as a user would (`kubectl get coralinstance`, `kubectl get pods`, `kubectl logs`)."""

    def __init__(
        self, missions: KindMissionStack, robot: str, name: str, domain: int, tree: str, **spec: Any
    ) -> None:
        self.missions = missions
        self.robot = robot
        self.name = name
        rs.create(missions.custom, missions.namespace, rs.system(name, robot, domain, tree, **spec))

    def instance(self) -> dict[str, Any]:
        return rs.instance(self.missions.custom, self.missions.namespace, self.name)

    def with_root(self, *roots: str) -> dict[str, Any]:
        return rs.with_root(self.missions.custom, self.missions.namespace, self.name, *roots)

    def reachable(self, status: str) -> dict[str, Any]:
        """The instance once `RobotReachable` has `status`, else {}."""
        item = self.instance()
        return item if rs.condition(item, "RobotReachable").get("status") == status else {}

    def pods(self, component: str | None = None) -> dict[str, Any]:
        """Component -> its pod."""
        listed = rs.pods(self.missions.core, self.missions.namespace, self.name, component)
        return {p.metadata.labels["coral.dev/component"]: p for p in listed}

    def running_in(self, node_name: str, timeout: float) -> dict[str, Any]:
        """Waits until the tree's active path goes through `node_name`; the instance then."""
        return wait_for(
            lambda: (i := self.instance()) and node_name in rs.tree(i).get("activePath", "") and i,
            timeout=timeout,
            message=lambda: f"the tree to run {node_name}: {self.instance()}\n{self.logs()}",
        )

    def logs(self) -> str:
        return (
            f"--- operator:\n{self.missions.operator_log_tail()}\n"
            f"--- executor:\n{self.missions.log_tail(self.robot, 'executor')}"
        )


def on_robot(running: clusters.Running, robot: str, *argv: str, check: bool = True) -> str:
    """`argv` run on the robot (inside its node container, as someone logged into the robot would);
    its output."""
    return running.engine.docker("exec", faults.node_of(running, robot), *argv, check=check).stdout


def crictl(running: clusters.Running, robot: str, *args: str) -> str:
    """`crictl` inside the robot's node, as an operator of the machine would run it; its output."""
    # crictl gives each call to the runtime 2 s by default; stopping a container on a busy robot
    # (its process killed, its task reaped) can take longer, and the stop goes on regardless.
    return on_robot(running, robot, "crictl", "--timeout", "60s", *args)


def stops_on_sigterm(script: str) -> str:
    """`script` for `sh -c` in a container that ends when the kubelet stops it, as a component
    would: the shell is the container's first process, which the kernel lets ignore SIGTERM, and
    each deletion of a system would wait out its pods' grace period (30 s) before a kill."""
    return f"trap 'exit 0' TERM; {{ {script}; }} & wait"


def fleet_system(name: str, domain: int, tree: str, **spec: Any) -> dict[str, Any]:
    """A CoralSystem over every robot of the cluster: one executor ticking `tree` at 10 Hz, and
    `spec`'s other fields (drivers, skillsets)."""
    return {
        "apiVersion": f"{rs.GROUP}/{rs.VERSION}",
        "kind": "CoralSystem",
        "metadata": {"name": name},
        "spec": {
            "robots": {"matchLabels": dict(FLEET_LABEL)},
            "ros": {"domainId": domain},
            "parameters": {"inline": f"{rs.SKILLSET}:\n  ros__parameters: {{}}\n"},
            "tree": {"tickRateHz": 10.0, "inline": tree},
            "executors": [{"name": "executor", "image": catalog.by_name()["executor"].reference}],
            **spec,
        },
    }


def pull_for(missions: KindMissionStack, robots: list[str], system: dict[str, Any]) -> None:
    """Has `robots` pull the images of `system` and the operator's helper before a test that times
    what follows (a cold pull would count against a startup's health timeout)."""
    # The chart's helper image is the operator's own.
    helper = ":".join(operatorchart.operator_image())
    nodes = [faults.node_of(missions.running, robot) for robot in robots]
    prepull.pull_system_images(missions.cluster.api_client, missions.namespace, nodes, system, helper)


def scale_operator(missions: KindMissionStack, replicas: int) -> None:
    """`kubectl scale` of the chart's operator Deployment; waits until exactly `replicas` of its pods
    exist, each Ready (none at all for zero: the operator is gone)."""
    release = missions.release
    missions.cluster.kubectl(
        "scale", "-n", release.namespace, f"deployment/{release.name}", f"--replicas={replicas}"
    )

    def settled() -> bool:
        pods = operatorchart.operator_pods(missions.cluster.api_client, release)
        ready = [
            p
            for p in pods
            if p.metadata.deletion_timestamp is None
            and any(c.type == "Ready" and c.status == "True" for c in p.status.conditions or [])
        ]
        return len(pods) == len(ready) == replicas

    wait_for(
        settled,
        timeout=180,
        interval=0.5,
        message=lambda: f"{replicas} operator pods, Ready: {missions.operator_log_tail(800)}",
    )


def container_address(running: clusters.Running, robot: str) -> str:
    """The address Docker gave the robot's node container on the cluster's network: what its Node
    must report as InternalIP (`faults.robot_address` reads that)."""
    network = clusters.network_name(running.name)
    template = f'{{{{(index .NetworkSettings.Networks "{network}").IPAddress}}}}'
    return running.engine.docker(
        "inspect", "--format", template, faults.node_of(running, robot)
    ).stdout.strip()


def started_at(status: k8s.V1ContainerStatus) -> datetime:
    """When a container started (running now, or since ended)."""
    state = status.state
    ran = state.running or state.terminated
    assert ran is not None and ran.started_at is not None, f"{status.name} never started"
    return ran.started_at
