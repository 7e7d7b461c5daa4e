"""Everything a mission needs on a cluster: the CRDs, a namespace, the operator and the robot runner.

`MissionStack` starts them in that order and stops them in reverse, also when start fails half
way; `coral demo` uses it over a throwaway control plane, the mission tests over the session's.
The operator is this checkout's (`python -m coral_operator`), watching only the stack's namespace,
its log in `<root>/operator.log`.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

from coral_operator.api.names import GROUP, VERSION
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_testbed.cluster.client import Cluster
from coral_testbed.missions import manifests
from coral_testbed.missions.entrypoints import reference_entrypoints
from coral_testbed.runner import RobotRunner
from coral_testbed.waiting import wait_for

ROOT = Path(__file__).resolve().parents[3]
CRDS = ROOT / "crds"
_ESTABLISHED = 'jsonpath={.status.conditions[?(@.type=="Established")].status}'


class MissionStack:
    """The operator and a robot runner over `robots`, for missions in `namespace`.

    Args:
        cluster: the control plane.
        namespace: created when missing (and then deleted by `stop`).
        robots: robot Node names the runner creates (or reuses) and runs pods for.
        root: folder for robot files and the operator's log.
        isolate: one network namespace per robot (needs root), so `cut_link` also cuts DDS.
    """

    def __init__(
        self, cluster: Cluster, namespace: str, robots: list[str], root: Path, isolate: bool = True
    ) -> None:
        self.cluster = cluster
        self.namespace = namespace
        self.robots = list(robots)
        self.root = Path(root)
        self.isolate = isolate
        self.runner: RobotRunner | None = None
        self.operator: subprocess.Popen[bytes] | None = None
        self.created_namespace = False
        self.custom = k8s.CustomObjectsApi(cluster.api_client)
        self.core = k8s.CoreV1Api(cluster.api_client)

    @property
    def operator_log(self) -> Path:
        return self.root / "operator.log"

    def __enter__(self) -> MissionStack:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.stop()

    def start(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        try:
            self._install_crds()
            self._ensure_namespace()
            self._start_operator()
            self.runner = RobotRunner(
                self.cluster.api_client,
                self.robots,
                root=self.root / "robots",
                isolate=self.isolate,
                entrypoints=reference_entrypoints(),
            )
            self.runner.start()
        except BaseException:
            self.stop()
            raise

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

    def _start_operator(self) -> None:
        env = {
            **self.cluster.env(),
            "PYTHONUNBUFFERED": "1",
            # The operator's policy opened for this namespace as an administrator would for these
            # missions: DDS over the host network, and the relay's site share beside the bags.
            "CORAL_POLICY_HOST_NETWORK_NAMESPACES": self.namespace,
            "CORAL_POLICY_HOST_PATH_PREFIXES": f"/var/lib/coral,{manifests.SITE_SHARE}",
        }
        with self.operator_log.open("ab") as log:
            self.operator = subprocess.Popen(
                [sys.executable, "-m", "coral_operator", "-n", self.namespace],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )

    def check_operator(self) -> None:
        """Raises with the log's tail when the operator exited."""
        if self.operator is not None and self.operator.poll() is not None:
            raise RuntimeError(
                f"the operator exited ({self.operator.returncode}):\n{self.operator_log_tail()}"
            )

    def operator_log_tail(self, chars: int = 3000) -> str:
        return self.operator_log.read_text(errors="replace")[-chars:] if self.operator_log.exists() else ""

    def apply(self, manifest: str) -> str:
        """`kubectl apply -n <namespace> -f -` of a manifest's text; kubectl's output."""
        return self.cluster.kubectl("apply", "-n", self.namespace, "-f", "-", input=manifest).stdout

    def instances(self) -> list[dict[str, Any]]:
        return self.custom.list_namespaced_custom_object(GROUP, VERSION, self.namespace, "coralinstances")[
            "items"
        ]

    def instance_of(self, robot: str) -> dict[str, Any] | None:
        return next((i for i in self.instances() if (i.get("spec") or {}).get("robot") == robot), None)

    def pod_dir(self, robot: str, component: str) -> Path | None:
        """The runner's folder of `component`'s pod on `robot` (logs, working directory), if any."""
        assert self.runner is not None
        pods = self.runner.robot_dir(robot) / "pods"
        # Pod names end in a five-character digest of their content (`<instance>-<component>-<hash>`).
        found = sorted(pods.glob(f"{self.namespace}_*-{component}-?????"), key=lambda p: p.stat().st_mtime)
        return found[-1] if found else None

    def place_bag(self, robot: str, bag: Path, robot_path: str) -> Path:
        """Makes the bag folder `bag` the robot's hostPath `robot_path`; returns where it is here."""
        assert self.runner is not None
        return manifests.place_bag(self.runner, robot, bag, robot_path)

    def component_output(self, robot: str, component: str, scratch: Path) -> Path | None:
        """The folder where `component` on `robot` wrote its outputs (`scratch` is not needed here)."""
        return self.pod_dir(robot, component)

    def log_tail(self, robot: str, component: str, chars: int = 2000) -> str:
        folder = self.pod_dir(robot, component)
        logs = list((folder / "logs").glob("*.log")) if folder else []
        return logs[0].read_text(errors="replace")[-chars:] if logs else f"(no log of {component} on {robot})"

    def delete_systems(self, timeout: float = 90) -> None:
        """Deletes every CoralSystem and waits until their pods are gone (the robots are free again)."""
        for system in self.custom.list_namespaced_custom_object(
            GROUP, VERSION, self.namespace, "coralsystems"
        )["items"]:
            self.custom.delete_namespaced_custom_object(
                GROUP, VERSION, self.namespace, "coralsystems", system["metadata"]["name"]
            )
        wait_for(
            lambda: not self.core.list_namespaced_pod(self.namespace).items and not self.instances(),
            timeout=timeout,
            interval=0.5,
            message=f"pods and CoralInstances of {self.namespace} gone",
        )

    def stop(self) -> None:
        """Stops the runner (its robots' processes, Nodes and network), then the operator."""
        if self.runner is not None:
            self.runner.stop(remove_nodes=True)
        if self.operator is not None and self.operator.poll() is None:
            os.killpg(self.operator.pid, signal.SIGTERM)
            try:
                self.operator.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(self.operator.pid, signal.SIGKILL)
                self.operator.wait(timeout=10)
        if self.created_namespace:
            try:
                self.core.delete_namespace(self.namespace)
            except ApiException as error:
                if error.status != 404:
                    raise
