"""What a mission on a cluster is made of, and a view of it in one namespace.

`MissionView` reads and feeds a mission in one namespace: `kubectl apply`, the CoralInstances, a
component's output (back with `kubectl cp`) and its logs. The constants say what a mission stack
brings up: the mission's images, the CRDs, the operator's node and the policy the operator's
chart opens for the mission's namespace. `coral_testbed.kind.missions.KindMissionStack` brings it
all up on a kind cluster (`coral demo`, the kind tests).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from coral_core import names
from coral_core.names import GROUP, VERSION
from kubernetes import client as k8s

from coral_testbed.cluster.client import Cluster
from coral_testbed.missions import manifests
from coral_testbed.waiting import wait_for

ROOT = Path(__file__).resolve().parents[3]
CRDS = ROOT / "crds"
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
    """A mission's resources in `namespace` of `cluster`."""

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

