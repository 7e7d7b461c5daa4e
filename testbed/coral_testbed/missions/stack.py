"""A mission on real robots: images in a registry, real kubelets, the operator by Helm.

`MissionView` reads and feeds a mission in one namespace of a local cluster: `kubectl apply`, the
CoralInstances, files placed on a robot through its host paths (`RealRobots.host_path`), a site
share between robots, what a container wrote (back with `kubectl cp`) and its logs. The mission
tests use it beside their fixtures' operator and robots.

`MissionStack` is a view that also brings up everything a mission needs, in this order, and stops
it in reverse (also when a start fails half way): the mission's images built into a registry (a
cache hit when the tree is unchanged), the CRDs and the namespace, the robots as real kubelets
with containerd plus one plain node for the operator, and the operator `helm install`ed there,
serving only the stack's namespace. `coral demo` runs it over a throwaway control plane.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coral_core import names
from coral_core.component_image import COMPONENT_UID
from coral_core.names import GROUP, VERSION
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_testbed import images
from coral_testbed.cluster import nodeconfig, operatorchart, processes
from coral_testbed.cluster.client import Cluster
from coral_testbed.images import registry
from coral_testbed.missions import manifests
from coral_testbed.waiting import wait_for

ROOT = Path(__file__).resolve().parents[3]
CRDS = ROOT / "crds"
_ESTABLISHED = 'jsonpath={.status.conditions[?(@.type=="Established")].status}'
OPERATOR_NODE = "operator-node"
MISSION_IMAGES = (
    "operator",
    "executor",
    "bag-player",
    "slam-skillset",
    "snapshot-skillset",
    "examples-skillset",
)
MISSION_FOLDERS = (manifests.BAGS, manifests.SITE_SHARE)
"""Robot folders the missions mount besides their namespace's own: the bags, and the relay's site
share, which an administrator places on the robots and opens for the missions' namespace."""
Echo = Callable[[str], None]
PROGRESS_WORDS = ("building", "built", "cached", "pulled")


def operator_policy(namespace: str) -> dict[str, tuple[str, ...]]:
    """The chart's `policy.*` opened for the missions in `namespace`, as an administrator would for
    robots running ROS 2 over DDS: the host network, and the folders of `MISSION_FOLDERS`."""
    return {
        "hostNetworkNamespaces": (namespace,),
        "hostPaths": tuple(f"{namespace}={folder}" for folder in MISSION_FOLDERS),
    }


class MissionView:
    """A mission's resources and robot files in `namespace` of a local `cluster` with real robots."""

    def __init__(self, cluster: Cluster, namespace: str) -> None:
        self.cluster = cluster
        self.namespace = namespace
        self.custom = k8s.CustomObjectsApi(cluster.api_client)
        self.core = k8s.CoreV1Api(cluster.api_client)

    def apply(self, manifest: str) -> str:
        """`kubectl apply -n <namespace> -f -` of a manifest's text; kubectl's output."""
        return self.cluster.kubectl("apply", "-n", self.namespace, "-f", "-", input=manifest).stdout

    def instances(self) -> list[dict[str, Any]]:
        plural = names.INSTANCE_PLURAL
        listed = self.custom.list_namespaced_custom_object(GROUP, VERSION, self.namespace, plural)
        return listed["items"]

    def instance_of(self, robot: str) -> dict[str, Any] | None:
        return next((i for i in self.instances() if (i.get("spec") or {}).get("robot") == robot), None)

    def place_bag(self, robot: str, bag: Path, robot_path: str) -> Path:
        """Copies the bag folder into `robot`'s `robot_path` (a link would point outside the robot's
        mount view, where its containers cannot follow it); returns where it is on this machine."""
        target = self.cluster.robots.host_path(robot, robot_path)
        if target.exists():
            shutil.rmtree(target)
        shutil.copytree(bag, target)
        return target

    def share_folder(self, server: str, clients: list[str], robot_path: str = manifests.SITE_SHARE) -> Path:
        """`server`'s `robot_path` mounted at the same path on `clients` (an NFS site share), owned
        by the components' user so their containers may write it; returns where it is here."""
        return self.cluster.robots.share_folder(server, clients, robot_path, owner=COMPONENT_UID)

    def pods(self, robot: str, component: str) -> list[k8s.V1Pod]:
        selector = f"{names.LABEL_COMPONENT}={component},{names.LABEL_ROBOT}={robot}"
        return list(self.core.list_namespaced_pod(self.namespace, label_selector=selector).items)

    def component_output(self, robot: str, component: str, scratch: Path) -> Path | None:
        """`kubectl cp` of the component's output folder (its $CORAL_OUTPUT_DIR) into `scratch`."""
        pods = self.pods(robot, component)
        if not pods:
            return None
        source = f"{pods[0].metadata.name}:{manifests.CONTAINER_OUTPUT_DIR}"
        result = self.cluster.kubectl(
            "cp", "-n", self.namespace, "-c", component, source, str(scratch), check=False, timeout=120
        )
        return scratch if result.returncode == 0 else None

    def log_tail(self, robot: str, component: str, chars: int = 2000) -> str:
        """The end of `kubectl logs` of the component's container on `robot` (or why there is none)."""
        pods = self.pods(robot, component)
        if not pods:
            return f"(no pod of {component} on {robot})"
        result = self.cluster.kubectl(
            "logs", "-n", self.namespace, pods[0].metadata.name, "-c", component, check=False, timeout=60
        )
        return (result.stdout + result.stderr)[-chars:]

    def delete_systems(self, timeout: float = 90) -> None:
        """Deletes every CoralSystem and waits until their pods are gone (the robots are free again)."""
        for system in self.custom.list_namespaced_custom_object(
            GROUP, VERSION, self.namespace, names.SYSTEM_PLURAL
        )["items"]:
            self.custom.delete_namespaced_custom_object(
                GROUP, VERSION, self.namespace, names.SYSTEM_PLURAL, system["metadata"]["name"]
            )
        wait_for(
            lambda: (
                not self.core.list_namespaced_pod(self.namespace, label_selector=names.LABEL_SYSTEM).items
                and not self.instances()
            ),
            timeout=timeout,
            interval=0.5,
            message=f"pods and CoralInstances of {self.namespace} gone",
        )


class MissionStack(MissionView):
    """The operator (by Helm) and real robots `robots` for missions in `namespace`.

    Args:
        cluster: a local control plane (real robots need its state folder).
        namespace: created when missing (and then deleted by `stop`).
        robots: real robots to start (their Nodes carry the robot label).
        root: folder for the registry's state.
        echo: receives one line per step.
    """

    def __init__(
        self, cluster: Cluster, namespace: str, robots: list[str], root: Path, echo: Echo = lambda _: None
    ) -> None:
        super().__init__(cluster, namespace)
        self.robots = list(robots)
        self.root = Path(root)
        self.echo = echo
        self.release = operatorchart.Release(
            name="coral-operator",
            namespace=namespace,
            watch_namespaces=(namespace,),
            policy=operator_policy(namespace),
        )
        self.created_namespace = False
        self._registry: processes.Recorded | None = None
        self._saved_registry_env: str | None = None

    def __enter__(self) -> MissionStack:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.stop()

    def start(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        try:
            address = self._serve_registry()
            self.echo(f"==> Images from the repository's Dockerfiles into the registry at {address}")
            images.build(list(MISSION_IMAGES), registry_address=address, progress=self._image_progress)
            self._install_crds()
            self._ensure_namespace()
            self._start_nodes()
            self.echo(f"$ helm install coral-operator charts/coral-operator -n {self.namespace} ...")
            assert self.cluster.bin_dir is not None
            pod = operatorchart.install(
                self.cluster.api_client, self.cluster.bin_dir / "helm", self.cluster.env(), self.release
            )
            self.echo(f"    the operator runs in pod {pod.metadata.name} on {pod.spec.node_name}")
        except BaseException:
            self.stop()
            raise

    def _start_nodes(self) -> None:
        """The robots and the operator's node, as real kubelets with containerd."""
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

    def _stop_nodes(self) -> None:
        if self.cluster.robots.names():
            self.cluster.robots.remove_all()

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

    def _install_crds(self) -> None:
        self.cluster.kubectl("apply", "--server-side", "--force-conflicts", "-f", str(CRDS))
        for crd in ("coralsystems.coral.dev", "coralinstances.coral.dev"):
            # `kubectl wait` fails outright while a new CRD has no status yet; poll instead.
            wait_for(
                lambda crd=crd: (
                    self.cluster.kubectl("get", "crd", crd, "-o", _ESTABLISHED, check=False).stdout == "True"
                ),
                timeout=60,
                interval=0.5,
                message=f"CRD {crd} Established",
            )

    def _ensure_namespace(self) -> None:
        try:
            self.core.create_namespace({"metadata": {"name": self.namespace}})
            self.created_namespace = True
        except ApiException as error:
            if error.status != 409:
                raise

        def default_account() -> bool:
            try:
                self.core.read_namespaced_service_account("default", self.namespace)
            except ApiException as error:
                if error.status == 404:
                    return False
                raise
            return True

        # Pods are refused until the controller manager made the namespace's default ServiceAccount.
        wait_for(
            default_account, timeout=60, interval=0.5, message=f"ServiceAccount default in {self.namespace}"
        )

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

    def stop(self) -> None:
        """Removes the real robots and the operator node, the registry this stack started, and the
        namespace when the stack created it."""
        try:
            self._stop_nodes()
        finally:
            if self._registry is not None:
                registry.stop(self._registry)
                self._registry = None
                if self._saved_registry_env is None:
                    os.environ.pop(nodeconfig.REGISTRY_ENV, None)
                else:
                    os.environ[nodeconfig.REGISTRY_ENV] = self._saved_registry_env
            if self.created_namespace:
                try:
                    self.core.delete_namespace(self.namespace)
                except ApiException as error:
                    if error.status != 404:
                        raise
