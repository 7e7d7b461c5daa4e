"""The Coral path: the operator as a subprocess and one CoralSystem over the whole fleet.

`OperatorProcess` runs `python -m coral_operator -n <namespace>` and samples its peak resident set
(VmHWM in /proc) until it stops. `run_coral` measures the time until every CoralInstance is Ready
(the system's `Ready` condition, current for its generation, with every robot counted ready) and
the time of a rolling update at `maxUnavailable: 10%` after a change to one environment variable
of every component, like the DaemonSet's update.
"""

from __future__ import annotations

import copy
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from coral_testbed.waiting import WaitTimeout, wait_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from fleet.robots import FLEET_LABEL

ROOT = Path(__file__).resolve().parents[2]
GROUP, VERSION, PLURAL = "coral.dev", "v1alpha1", "coralsystems"
NAME = "mission"


class OperatorProcess:
    """The operator serving one namespace, with its peak RSS sampled from /proc."""

    def __init__(
        self,
        env: dict[str, str],
        namespace: str,
        log: Path,
        metrics: str | None = None,
        checkout: Path | None = None,
    ) -> None:
        """`metrics`: ADDRESS:PORT to serve the operator's metrics on; off when None. `checkout`:
        run the operator of that checkout, from its own .venv (default: this one's)."""
        self.log = log
        self.peak_kib = 0
        self._stop = threading.Event()
        self.process = subprocess.Popen(
            [str(checkout / ".venv" / "bin" / "python") if checkout else sys.executable]
            + ["-m", "coral_operator", "-n", namespace],
            cwd=checkout,
            # The benchmark's systems use the host network, as robots running DDS do.
            env={
                **env,
                **policy_environment(namespace),
                "PYTHONUNBUFFERED": "1",
                **({"CORAL_OPERATOR_METRICS": metrics} if metrics else {}),
            },
            stdout=log.open("w"),
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        self._sampler = threading.Thread(target=self._sample, daemon=True)
        self._sampler.start()

    def _read_hwm(self) -> int:
        try:
            for line in Path(f"/proc/{self.process.pid}/status").read_text().splitlines():
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
        except (OSError, ValueError):
            pass
        return 0

    def _sample(self) -> None:
        while not self._stop.wait(0.5):
            self.peak_kib = max(self.peak_kib, self._read_hwm())

    @property
    def peak_mb(self) -> float:
        return max(self.peak_kib, self._read_hwm()) / 1024

    def alive(self) -> bool:
        return self.process.poll() is None

    def stop(self) -> None:
        self.peak_kib = max(self.peak_kib, self._read_hwm())
        self._stop.set()
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=10)


def build_system(
    namespace: str, revision: str, max_unavailable: str, layout: str = "PodPerComponent"
) -> dict[str, Any]:
    """The fleet example over the benchmark's robots, with the same images as the DaemonSet."""
    manifest = copy.deepcopy(yaml.safe_load((ROOT / "examples" / "fleet" / "mission.yaml").read_text()))
    manifest["metadata"] = {"name": NAME, "namespace": namespace}
    spec = manifest["spec"]
    spec["robots"] = {"matchLabels": {FLEET_LABEL: "bench"}}
    for role in ("drivers", "skillsets", "executors"):
        for component in spec.get(role, []):
            env = [e for e in component.get("env", []) if e["name"] != "MISSION_REVISION"]
            component["env"] = [*env, {"name": "MISSION_REVISION", "value": revision}]
    spec["rollout"] = {"maxUnavailable": max_unavailable}
    spec["layout"] = layout
    return manifest


def policy_environment(namespace: str) -> dict[str, str]:
    """The operator's policy opened for the benchmark's system as an administrator would: the host
    network (robots running DDS) and the robot folders its components mount (the example's bags)."""
    spec = build_system(namespace, "0", "10%")["spec"]
    folders = sorted(
        {
            mount["hostPath"]
            for role in ("drivers", "skillsets", "executors")
            for component in spec.get(role, [])
            for mount in component.get("hostPaths", [])
        }
    )
    return {
        "CORAL_POLICY_HOST_NETWORK_NAMESPACES": namespace,
        "CORAL_POLICY_HOST_PATHS": ",".join(f"{namespace}={folder}" for folder in folders),
    }


def _system(custom: k8s.CustomObjectsApi, namespace: str, name: str) -> dict[str, Any] | None:
    try:
        return custom.get_namespaced_custom_object(GROUP, VERSION, namespace, PLURAL, name)
    except ApiException as error:
        if error.status == 404:
            return None
        raise


def system_settled(body: dict[str, Any] | None, count: int) -> bool:
    """Ready for the current generation with every robot on the newest revision and ready."""
    if not body:
        return False
    status = body.get("status") or {}
    generation = body["metadata"].get("generation")
    ready = next((c for c in status.get("conditions") or [] if c.get("type") == "Ready"), {})
    robots = status.get("robots") or {}
    return (
        status.get("observedGeneration") == generation
        and ready.get("status") == "True"
        and ready.get("observedGeneration") == generation
        and robots.get("ready") == count
        and robots.get("updated") == count
    )


def wait_operator_serving(
    api: k8s.ApiClient, namespace: str, operator: OperatorProcess, timeout: float
) -> None:
    """Creates a CoralSystem matching no robot and waits until the operator has written its status."""
    custom = k8s.CustomObjectsApi(api)
    probe = build_system(namespace, "0", "10%")
    probe["metadata"]["name"] = "warm-up"
    probe["spec"]["robots"] = {"matchLabels": {FLEET_LABEL: "nobody"}}
    custom.create_namespaced_custom_object(GROUP, VERSION, namespace, PLURAL, probe)

    def served() -> bool:
        if not operator.alive():
            raise RuntimeError(f"the operator exited; see {operator.log}")
        body = _system(custom, namespace, "warm-up")
        return bool(body and (body.get("status") or {}).get("observedGeneration"))

    wait_for(served, timeout=timeout, interval=0.5, message="the operator to reconcile a first CoralSystem")
    custom.delete_namespaced_custom_object(GROUP, VERSION, namespace, PLURAL, "warm-up")


@dataclass
class CoralResult:
    ready_seconds: float
    update_seconds: float
    stalled: str = ""
    """Which phase did not finish within the timeout (its figure is then the timeout), if any."""


def _timed(settled: Any, timeout: float, message: str) -> tuple[float, bool]:
    """Seconds until `settled`, and whether it got there (False: the timeout, reported as a miss)."""
    began = time.monotonic()
    try:
        wait_for(settled, timeout=timeout, interval=0.5, message=message)
    except WaitTimeout:
        return time.monotonic() - began, False
    return time.monotonic() - began, True


def run_coral(
    api: k8s.ApiClient,
    namespace: str,
    count: int,
    operator: OperatorProcess,
    timeout: float,
    layout: str = "PodPerComponent",
    between: Callable[[], None] | None = None,
) -> CoralResult:
    """Deploy, wait until settled, call `between` (the benchmark counts the first deployment's
    requests there), then roll the update and wait again."""
    custom = k8s.CustomObjectsApi(api)

    def settled() -> bool:
        if not operator.alive():
            raise RuntimeError(f"the operator exited; see {operator.log}")
        return system_settled(_system(custom, namespace, NAME), count)

    custom.create_namespaced_custom_object(
        GROUP, VERSION, namespace, PLURAL, build_system(namespace, "1", "10%", layout)
    )
    ready, done = _timed(settled, timeout, f"CoralSystem on {count} robots to become Ready")
    if not done:
        return CoralResult(ready_seconds=ready, update_seconds=float("inf"), stalled="ready")
    if between is not None:
        between()
    custom.patch_namespaced_custom_object(
        GROUP,
        VERSION,
        namespace,
        PLURAL,
        NAME,
        {"spec": build_system(namespace, "2", "10%", layout)["spec"]},
        _content_type="application/merge-patch+json",
    )
    update, done = _timed(settled, timeout, f"CoralSystem rolling update over {count} robots")
    return CoralResult(ready_seconds=ready, update_seconds=update, stalled="" if done else "update")


def delete_system(api: k8s.ApiClient, namespace: str, timeout: float) -> None:
    """Delete the benchmark's system and wait until its instances and pods are gone."""
    custom = k8s.CustomObjectsApi(api)
    core = k8s.CoreV1Api(api)
    custom.delete_namespaced_custom_object(GROUP, VERSION, namespace, PLURAL, NAME)

    def gone() -> bool:
        instances = custom.list_namespaced_custom_object(GROUP, VERSION, namespace, "coralinstances", limit=1)
        return not instances["items"] and not core.list_namespaced_pod(namespace, limit=1).items

    wait_for(gone, timeout=timeout, interval=1.0, message="the benchmark's system and pods to be deleted")


def cpu_seconds(pid: int) -> float:
    """User plus system CPU time of a live process, from /proc (0 when it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def kube_env(kubeconfig: Path) -> dict[str, str]:
    """This process's environment, pointed at the benchmark's control plane."""
    return {**os.environ, "KUBECONFIG": str(kubeconfig)}


def apply_crds(env: dict[str, str], folder: Path = ROOT / "crds") -> bool:
    """`kubectl apply` of `folder` and a wait until the CRDs are established; False (stderr printed)
    on failure. Applying another checkout's CRDs over these replaces their schemas."""
    from coral_testbed.cluster import binaries

    kubectl = binaries.find_kubectl(None)
    result = subprocess.run(
        [kubectl, "apply", "--server-side", "--force-conflicts", "-f", str(folder)],
        env=env,
        capture_output=True,
        text=True,
    )
    if result.returncode != 0:
        print(result.stderr, file=sys.stderr)
        return False
    subprocess.run(
        [kubectl, "wait", "--for=condition=Established", "--timeout=60s", "crd", "--all"],
        env=env,
        capture_output=True,
        text=True,
    )
    return True
