"""One simulated robot's kubelet: keeps its Node alive and runs the pods bound to it.

`runner.RobotRunner` starts one `RobotAgent` thread per robot. Each pass of its loop (every
`interval` seconds) it renews the Node Lease and, now and then, the Ready condition; lists the pods
bound to the robot; starts a `pods.PodWorker` for each new one, stops the workers of deleted
pods (then removes the pod object, as a kubelet does), steps every worker and patches the pod
status that changed. While the robot's link is cut the agent makes no API call at all, but keeps
supervising its processes; it reports again as soon as the link is restored.
"""

from __future__ import annotations

import logging
import threading
import time
from datetime import UTC, datetime
from typing import Any

from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_testbed.runner import nodes, pods, podspec, volumes

log = logging.getLogger(__name__)

NODE_STATUS_EVERY = 20.0
LEASE_EVERY = 10.0
TERMINAL = ("Succeeded", "Failed")


class RobotAgent:
    """See the module docstring."""

    def __init__(
        self,
        robot: pods.Robot,
        api: k8s.ApiClient,
        runner_id: str,
        adopt: bool,
        interval: float = 0.3,
    ) -> None:
        self.robot = robot
        self.core = k8s.CoreV1Api(api)
        self.coordination = k8s.CoordinationV1Api(api)
        self.runner_id = runner_id
        self.adopt = adopt
        self.interval = interval
        self.connected = True
        self.workers: dict[str, pods.PodWorker] = {}
        self.last_sent: dict[str, dict[str, Any]] = {}
        self.finished: set[str] = set()
        self.errors: list[str] = []
        self._node_uid = ""
        self._next_lease = 0.0
        self._next_node_status = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"robot-{robot.name}", daemon=True)

    def set_connected(self, connected: bool) -> None:
        """Link state of the robot; on reconnection the kubelet reports at once, as after an outage."""
        if connected and not self.connected:
            self._next_lease = self._next_node_status = 0.0
        self.connected = connected

    def register(self) -> None:
        """Creates or adopts the Node and reports it Ready (called before the loop starts)."""
        nodes.ensure_node(self.core, self.robot.name, self.runner_id, self.adopt)
        self._node_uid = self.core.read_node(self.robot.name).metadata.uid
        self._heartbeat(force=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self, report: bool = True) -> None:
        self._stop.set()
        self._thread.join(timeout=30)
        for worker in self.workers.values():
            worker.kill()
        if report and self.connected:
            try:
                status = nodes.build_node_status(
                    False, "RobotRunnerStopped", "the robot runner stopped", self.robot.address, _now()
                )
                nodes.report_node(self.core, self.robot.name, status)
            except ApiException as error:
                log.warning("Node %s status not reported at stop: %s", self.robot.name, error.reason)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._pass()
            except Exception as error:  # A failed pass is retried; the loop must live.
                message = f"{type(error).__name__}: {error}"
                if not self.errors or self.errors[-1] != message:
                    log.warning("Robot %s pass failed: %s", self.robot.name, message)
                self.errors = [*self.errors[-19:], message]
            self._stop.wait(self.interval)

    def _pass(self) -> None:
        if self.connected:
            self._heartbeat()
            self._sync_pods()
        for worker in list(self.workers.values()):
            worker.step()
        if self.connected:
            self._report()

    def _heartbeat(self, force: bool = False) -> None:
        now = time.monotonic()
        if force or now >= self._next_lease:
            nodes.renew_lease(self.coordination, self._node_uid, self.robot.name, _now())
            self._next_lease = now + LEASE_EVERY
        if force or now >= self._next_node_status:
            status = nodes.build_node_status(
                True, "KubeletReady", "robot runner is posting ready status", self.robot.address, _now()
            )
            nodes.report_node(self.core, self.robot.name, status)
            self._next_node_status = now + NODE_STATUS_EVERY

    def _sync_pods(self) -> None:
        listed = self.core.list_pod_for_all_namespaces(field_selector=f"spec.nodeName={self.robot.name}")
        seen: set[str] = set()
        for item in listed.items:
            pod = self.core.api_client.sanitize_for_serialization(item)
            uid = pod["metadata"]["uid"]
            seen.add(uid)
            worker = self.workers.get(uid)
            if worker is None:
                if pod["metadata"].get("deletionTimestamp"):
                    self._delete(pod)
                    continue
                if uid in self.finished or (pod.get("status") or {}).get("phase") in TERMINAL:
                    continue
                worker = pods.PodWorker(pod, self.robot, self._lookup, self._token)
                self.workers[uid] = worker
                log.info("Pod %s started on robot %s", worker.key, self.robot.name)
            worker.update(pod)
            if _conditions_differ(pod.get("status") or {}, self.last_sent.get(uid)):
                # Someone else changed the pod's status (the node controller marks the pods of an
                # unreachable robot not Ready): send ours again, as the kubelet's status manager does.
                self.last_sent.pop(uid, None)
            if pod["metadata"].get("deletionTimestamp"):
                grace = pod["metadata"].get("deletionGracePeriodSeconds")
                worker.terminate(float(grace if grace is not None else 30))
        for uid in list(self.workers):
            if uid not in seen:
                # Force-deleted: nothing left to report to, stop at once.
                self.workers.pop(uid).kill(timeout=2)
                self.last_sent.pop(uid, None)
        self.finished &= seen

    def _report(self) -> None:
        for uid, worker in list(self.workers.items()):
            if worker.terminating_since is not None:
                if worker.stopped:
                    self._delete(worker.pod)
                    self.workers.pop(uid)
                    self.last_sent.pop(uid, None)
                continue
            status = worker.status()
            if status != self.last_sent.get(uid):
                meta = worker.pod["metadata"]
                try:
                    self.core.patch_namespaced_pod_status(
                        meta["name"], meta["namespace"], {"status": status}, _content_type=nodes.MERGE_PATCH
                    )
                except ApiException as error:
                    if error.status != 404:
                        raise
                self.last_sent[uid] = status
            if status["phase"] in ("Succeeded", "Failed") and worker.stopped:
                self.finished.add(uid)
                self.workers.pop(uid)
                self.last_sent.pop(uid, None)

    def _delete(self, pod: dict[str, Any]) -> None:
        meta = pod["metadata"]
        try:
            self.core.delete_namespaced_pod(
                meta["name"],
                meta["namespace"],
                # Grace 0 in the body: the client sends the body, which overrides the query parameter.
                body={"gracePeriodSeconds": 0, "preconditions": {"uid": meta["uid"]}},
            )
        except ApiException as error:
            if error.status not in (404, 409):
                raise

    def _lookup(self, kind: str, namespace: str, name: str) -> dict[str, str] | None:
        try:
            if kind == "ConfigMap":
                return dict(self.core.read_namespaced_config_map(name, namespace).data or {})
            if kind == "Secret":
                return volumes.decode_secret(self.core.read_namespaced_secret(name, namespace).data or {})
        except ApiException as error:
            if error.status == 404:
                return None
            raise
        raise podspec.ContainerConfigError(f"cannot look up objects of kind {kind}")

    def _token(self, namespace: str, account: str, pod: str, uid: str) -> str:
        body = {
            "spec": {
                "expirationSeconds": 86400,
                "boundObjectRef": {"apiVersion": "v1", "kind": "Pod", "name": pod, "uid": uid},
            }
        }
        try:
            response = self.core.create_namespaced_service_account_token(account, namespace, body)
        except ApiException as error:
            raise podspec.ContainerConfigError(
                f"ServiceAccount {namespace}/{account}: token request failed ({error.status} {error.reason})"
            ) from error
        return str(response.status.token)


def _conditions_differ(current: dict[str, Any], sent: dict[str, Any] | None) -> bool:
    """True when a condition we sent has another status on the API server now."""
    if sent is None:
        return False
    ours = {c["type"]: c["status"] for c in sent.get("conditions") or []}
    theirs = {c.get("type"): c.get("status") for c in current.get("conditions") or []}
    return any(theirs.get(kind) != status for kind, status in ours.items())


def _now() -> datetime:
    return datetime.now(UTC)
