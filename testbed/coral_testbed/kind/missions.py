"""Missions on a kind cluster: `coral demo --cluster kind` (what `make demo` runs).

`demo_cluster` makes a throwaway kind cluster (one worker per robot and one for the operator) and
deletes it again, with the project's dockerd when this call started it. `KindMissionStack` is the
mission stack of `coral_testbed.missions.stack` on it: images from the cluster's registry, the
robots are the kind workers, files are placed on a robot inside its node container.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path

from coral_testbed.cluster import binaries, operatorchart
from coral_testbed.cluster.client import Cluster
from coral_testbed.kind import clusters, engine, faults, provisioning
from coral_testbed.missions import manifests, stack

DEMO_CLUSTER = "coral-demo"
DEMO_CLUSTERS = {"slam": DEMO_CLUSTER, "relay": "relay-demo", "site": "site-demo"}
"""The kind cluster of each mission's demo: demos of different missions on one machine do not collide."""


@contextlib.contextmanager
def demo_cluster(
    robots: list[str], echo: Callable[[str], None], share: Path, name: str = DEMO_CLUSTER
) -> Iterator[tuple[clusters.Running, Cluster]]:
    """A kind cluster `name` for the mission's robots and the operator's node, with the host folder
    `share` bound at the site share's path into every robot (an NFS mount on a site); deleted on
    the way out."""
    engine_was_running = engine.project_engine_running()
    ready = provisioning.ensure(lambda line: echo(f"    {line}"))
    try:
        running = clusters.create(
            name,
            {robot: {} for robot in robots},
            ready.engine,
            ready.node_image,
            lambda line: echo(f"    {line}"),
            extra_workers={stack.OPERATOR_NODE: {operatorchart.OPERATOR_NODE_LABEL: "true"}},
            robot_mounts={manifests.SITE_SHARE: str(share)},
        )
        cluster = Cluster(running.kubeconfig, binaries.find_bin_dir(("kubectl", "helm")), is_local=False)
        try:
            yield running, cluster
        finally:
            cluster.close()
    finally:
        echo(f"==> Deleting kind cluster {name}")
        clusters.delete(name, ready.engine, lambda line: echo(f"    {line}"))
        if not engine_was_running and clusters.stop_engine_unless_used(ready.engine):
            echo("==> Stopped the project's dockerd")


class KindMissionStack(stack.MissionStack):
    """The operator (by Helm) on a kind cluster whose workers are the robots; see `MissionStack`."""

    def __init__(
        self,
        running: clusters.Running,
        cluster: Cluster,
        namespace: str,
        robots: list[str],
        root: Path,
        echo: Callable[[str], None] = lambda _: None,
        share: Path | None = None,
    ) -> None:
        super().__init__(cluster, namespace, robots, root, echo)
        self.running = running
        self.share = share
        """The host folder bound at the site share's path into every robot, if any."""

    def _serve_registry(self) -> str:
        return self.running.registry_address

    def _start_nodes(self) -> None:
        self.echo(f"==> Robots {', '.join(self.robots)} are kind workers; {stack.OPERATOR_NODE} is one too")

    def _stop_nodes(self) -> None:
        """The kind cluster's nodes go with the cluster (`demo_cluster`)."""

    def place_bag(self, robot: str, bag: Path, robot_path: str) -> Path:
        """Copies the bag folder to `robot_path` inside the robot's node container."""
        node = faults.node_of(self.running, robot)
        self.running.engine.docker("exec", node, "rm", "-rf", robot_path)
        self.running.engine.docker("exec", node, "mkdir", "-p", str(Path(robot_path).parent))
        self.running.engine.docker("cp", str(bag), f"{node}:{robot_path}")
        return Path(f"{node}:{robot_path}")

    def share_folder(self, server: str, clients: list[str], robot_path: str = manifests.SITE_SHARE) -> Path:
        """The site share every robot's node has bound at `robot_path` since the cluster was made."""
        if self.share is None or robot_path != manifests.SITE_SHARE:
            raise ValueError(f"this cluster's robots share no folder at {robot_path}")
        return self.share
