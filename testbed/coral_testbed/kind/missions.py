"""Missions on a kind cluster: `coral demo` (what `make demo` runs) and the kind tests.

`demo_cluster` makes a throwaway kind cluster (one worker per robot and one for the operator) and
deletes it again, with the project's dockerd when no other kind cluster runs on it. `KindMissionStack` brings
up everything a mission needs on such a cluster, in this order, and stops it in reverse (also when
a start fails half way): the mission's images built into the cluster's registry (a cache hit when
the tree is unchanged), the CRDs and the namespace, and the operator `helm install`ed on the
operator's node, serving only the stack's namespace. The robots are the kind workers; files are
placed on a robot inside its node container.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path

from kubernetes.client.exceptions import ApiException

from coral_testbed import images
from coral_testbed.cluster import binaries, operatorchart
from coral_testbed.cluster.client import Cluster
from coral_testbed.kind import clusters, faults, provisioning
from coral_testbed.missions import manifests, stack
from coral_testbed.waiting import wait_for

_ESTABLISHED = 'jsonpath={.status.conditions[?(@.type=="Established")].status}'
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
        if clusters.stop_engine_unless_used(ready.engine):
            echo("==> Stopped the project's dockerd")


class KindMissionStack(stack.MissionView):
    """The operator (by Helm) for missions in `namespace` on a kind cluster whose workers are the robots.

    Args:
        running: the kind cluster (its registry, its node containers).
        cluster: a handle on it.
        namespace: created when missing (and then deleted by `stop`).
        robots: the kind workers the missions run on.
        root: a folder of the stack's own.
        echo: receives one line per step.
        share: the host folder bound at the site share's path into every robot, if any.
    """

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
        super().__init__(cluster, namespace)
        self.running = running
        self.robots = list(robots)
        self.root = Path(root)
        self.echo = echo
        self.share = share
        self.release = operatorchart.Release(
            name="coral-operator",
            namespace=namespace,
            watch_namespaces=(namespace,),
            policy=stack.operator_policy(namespace),
        )
        self.created_namespace = False

    def __enter__(self) -> KindMissionStack:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.stop()

    def start(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        try:
            address = self.running.registry_address
            self.echo(f"==> Images from the repository's Dockerfiles into the registry at {address}")
            images.build(list(stack.MISSION_IMAGES), registry_address=address, progress=self._image_progress)
            self._install_crds()
            self._ensure_namespace()
            self.echo(
                f"==> Robots {', '.join(self.robots)} are kind workers; {stack.OPERATOR_NODE} is one too"
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
        if said.startswith(stack.PROGRESS_WORDS):
            self.echo(f"    {line}")

    def _install_crds(self) -> None:
        self.cluster.kubectl("apply", "--server-side", "--force-conflicts", "-f", str(stack.CRDS))
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
        """Deletes the namespace when the stack created it (the robots go with the kind cluster)."""
        if self.created_namespace:
            try:
                self.core.delete_namespace(self.namespace)
            except ApiException as error:
                if error.status != 404:
                    raise

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
