"""A mission's stack on real robots: images in a registry, real kubelets, the operator by Helm.

`RealMissionStack` is `MissionStack` with the robot runner replaced by what a cluster has: it
builds the mission's images (a cache hit when the tree is unchanged) into a registry, starts the
robots as real kubelets with containerd plus one plain node for the operator, and `helm install`s
the chart there, serving only the stack's namespace. Files reach a robot through its host paths
(`RealRobots.host_path`); what a container wrote comes back with `kubectl cp`.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

from coral_testbed import images
from coral_testbed.cluster import nodeconfig, operatorchart, processes
from coral_testbed.cluster.client import Cluster
from coral_testbed.images import registry
from coral_testbed.missions import manifests
from coral_testbed.missions.stack import MissionStack

OPERATOR_NODE = "operator-node"
MISSION_IMAGES = ("operator", "executor", "bag-player", "slam-skillset", "snapshot-skillset")
Echo = Callable[[str], None]
PROGRESS_WORDS = ("building", "built", "cached", "pulled")


class RealMissionStack(MissionStack):
    """The operator (by Helm) and real robots `robots` for missions in `namespace`.

    Args:
        cluster: a local control plane (real robots need its state folder).
        namespace: created when missing.
        robots: real robots to start (their Nodes carry the robot label).
        root: folder for the registry's state.
        echo: receives one line per step.
    """

    def __init__(
        self, cluster: Cluster, namespace: str, robots: list[str], root: Path, echo: Echo = lambda _: None
    ) -> None:
        super().__init__(cluster, namespace, robots, root, isolate=True)
        self.echo = echo
        self.release = operatorchart.Release(
            name="coral-operator",
            namespace=namespace,
            watch_namespaces=(namespace,),
            policy={"hostNetworkNamespaces": (namespace,)},
        )
        self._registry: processes.Recorded | None = None
        self._saved_registry_env: str | None = None

    def start(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        try:
            address = self._serve_registry()
            self.echo(f"==> Images from the repository's Dockerfiles into the registry at {address}")
            images.build(list(MISSION_IMAGES), registry_address=address, progress=self._image_progress)
            self._install_crds()
            self._ensure_namespace()
            self.echo(
                f"==> Starting real robots {', '.join(self.robots)} and {OPERATOR_NODE}"
                " (a kubelet and a containerd each)"
            )
            fleet = self.cluster.robots
            fleet.add(self.robots, progress=lambda line: self.echo(f"    {line}"))
            fleet.add(
                [OPERATOR_NODE],
                {operatorchart.OPERATOR_NODE_LABEL: "true"},
                progress=lambda line: self.echo(f"    {line}"),
                robot=False,
            )
            self.echo(f"$ helm install coral-operator charts/coral-operator -n {self.namespace} ...")
            assert self.cluster.bin_dir is not None
            pod = operatorchart.install(
                self.cluster.api_client, self.cluster.bin_dir / "helm", self.cluster.env(), self.release
            )
            self.echo(f"    the operator runs in pod {pod.metadata.name} on {pod.spec.node_name}")
        except BaseException:
            self.stop()
            raise

    def _image_progress(self, line: str) -> None:
        # One line when an image starts building and one when it is done; its build steps and
        # pip's output are in the builder's log files.
        _, _, said = line.partition(": ")
        if said.startswith(PROGRESS_WORDS):
            self.echo(f"    {line}")

    def _serve_registry(self) -> str:
        """The registry robots pull from: the configured one when it serves, else one of our own."""
        configured = registry.configured_address()
        if registry.is_serving(configured):
            return configured
        address = registry.free_address()
        self._registry = registry.start(address, images.registry_storage(), self.root / "registry")
        # Robots read the registry's address when they start.
        self._saved_registry_env = os.environ.get(nodeconfig.REGISTRY_ENV)
        os.environ[nodeconfig.REGISTRY_ENV] = address
        return address

    def check_operator(self) -> None:
        """Raises with the operator's log when its pod restarted or went away."""
        pods = operatorchart.operator_pods(self.cluster.api_client, self.release)
        restarts = sum(s.restart_count for p in pods for s in (p.status.container_statuses or []))
        if not pods or restarts:
            raise RuntimeError(f"the operator's pod restarted or is gone:\n{self.operator_log_tail()}")

    def operator_log_tail(self, chars: int = 3000) -> str:
        result = self.cluster.kubectl(
            "logs", "-n", self.namespace, f"deployment/{self.release.name}", check=False
        )
        return (result.stdout + result.stderr)[-chars:]

    def place_bag(self, robot: str, bag: Path, robot_path: str) -> Path:
        """Copies the bag folder into `robot`'s `robot_path` (a link would point outside the robot's
        mount view, where its containers cannot follow it); returns where it is on this machine."""
        target = self.cluster.robots.host_path(robot, robot_path)
        if target.exists():
            shutil.rmtree(target)
        shutil.copytree(bag, target)
        return target

    def component_output(self, robot: str, component: str, scratch: Path) -> Path | None:
        """`kubectl cp` of the component's output folder (its $CORAL_OUTPUT_DIR) into `scratch`."""
        selector = f"coral.dev/component={component},coral.dev/robot={robot}"
        pods = self.core.list_namespaced_pod(self.namespace, label_selector=selector).items
        if not pods:
            return None
        source = f"{pods[0].metadata.name}:{manifests.CONTAINER_OUTPUT_DIR}"
        result = self.cluster.kubectl(
            "cp", "-n", self.namespace, "-c", component, source, str(scratch), check=False, timeout=120
        )
        return scratch if result.returncode == 0 else None

    def log_tail(self, robot: str, component: str, chars: int = 2000) -> str:
        selector = f"coral.dev/component={component},coral.dev/robot={robot}"
        result = self.cluster.kubectl(
            "logs", "-n", self.namespace, "-l", selector, "-c", component, "--tail=-1", check=False
        )
        return (result.stdout + result.stderr)[-chars:]

    def stop(self) -> None:
        """Removes the real robots and the operator node, then the registry this stack started."""
        try:
            if self.cluster.robots.names():
                self.cluster.robots.remove_all()
        finally:
            if self._registry is not None:
                registry.stop(self._registry)
                self._registry = None
                if self._saved_registry_env is None:
                    os.environ.pop(nodeconfig.REGISTRY_ENV, None)
                else:
                    os.environ[nodeconfig.REGISTRY_ENV] = self._saved_registry_env
