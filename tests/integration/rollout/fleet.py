"""Reading and steering a rollout from the rollout integration tests (the API a user's tools see)."""

from __future__ import annotations

import copy
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import yaml
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

ROOT = Path(__file__).resolve().parents[3]
GROUP, VERSION = "coral.dev", "v1alpha1"


def mission(name: str, fleet: str, rollout: dict[str, Any], revision: str = "1") -> dict[str, Any]:
    """The fleet example over this test's robots, with a rollout policy and a revision marker."""
    manifest = copy.deepcopy(yaml.safe_load((ROOT / "examples" / "fleet" / "mission.yaml").read_text()))
    manifest["metadata"] = {"name": name}
    spec = manifest["spec"]
    spec["robots"] = {"matchLabels": {"fleet": fleet}}
    spec["rollout"] = rollout
    set_revision(spec, revision)
    return manifest


def set_revision(spec: dict[str, Any], revision: str) -> None:
    """Change an environment variable of the skillset: a new revision that restarts every robot."""
    for component in spec["skillsets"]:
        env = [e for e in component.get("env", []) if e["name"] != "MISSION_REVISION"]
        component["env"] = [*env, {"name": "MISSION_REVISION", "value": revision}]


class Fleet:
    def __init__(self, api_client: k8s.ApiClient, namespace: str, name: str) -> None:
        self.custom = k8s.CustomObjectsApi(api_client)
        self.core = k8s.CoreV1Api(api_client)
        self.namespace = namespace
        self.name = name

    def create(self, manifest: dict[str, Any]) -> None:
        self.custom.create_namespaced_custom_object(GROUP, VERSION, self.namespace, "coralsystems", manifest)

    def system(self) -> dict[str, Any]:
        return self.custom.get_namespaced_custom_object(
            GROUP, VERSION, self.namespace, "coralsystems", self.name
        )

    def rollout(self) -> dict[str, Any]:
        return (self.system().get("status") or {}).get("rollout") or {}

    def change(self, revision: str) -> None:
        spec = self.system()["spec"]
        set_revision(spec, revision)
        self.custom.patch_namespaced_custom_object(
            GROUP,
            VERSION,
            self.namespace,
            "coralsystems",
            self.name,
            {"spec": {"skillsets": spec["skillsets"]}},
            _content_type="application/merge-patch+json",
        )

    def instances(self) -> dict[str, dict[str, Any]]:
        items = self.custom.list_namespaced_custom_object(GROUP, VERSION, self.namespace, "coralinstances")[
            "items"
        ]
        return {item["spec"]["robot"]: item for item in items}

    def revisions(self) -> dict[str, str]:
        return {robot: item["spec"]["revision"] for robot, item in self.instances().items()}

    def set_tree(self, robot: str, root: str) -> None:
        """Write the tree status the robot's executor would write through its status sink.

        A real executor reports seconds after its pod was made (it has to start first); reports
        are stamped to the second, and one stamped in the second its executor's pod was made may
        be the previous executor's, which the operator rightly ignores. So the report waits until
        the clock is past that second, as a running executor's always is.
        """
        instance = self.instances()[robot]["metadata"]["name"]
        # Any of the robot's pods: with one pod per robot the executor's is the robot's pod.
        pods = self.core.list_namespaced_pod(self.namespace, label_selector=f"coral.dev/robot={robot}").items
        newest = max((pod.metadata.creation_timestamp for pod in pods), default=None)
        if newest is not None:
            wait_for(
                lambda: datetime.now(UTC).replace(microsecond=0) > newest,
                timeout=5,
                interval=0.05,
                message="the second the executor's pod was made to pass",
            )
        self.custom.patch_namespaced_custom_object_status(
            GROUP,
            VERSION,
            self.namespace,
            "coralinstances",
            instance,
            {
                "status": {
                    "tree": {
                        "rootStatus": root,
                        "activePath": "Patrol/patrol",
                        "tickCount": 10,
                        # As the executor's status sink stamps every report.
                        "updatedAt": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
                    }
                }
            },
            _content_type="application/merge-patch+json",
        )

    def pod_uids(self, robot: str) -> dict[str, str]:
        """Component name to pod uid on one robot (a replaced pod has a new uid)."""
        pods = self.core.list_namespaced_pod(self.namespace, label_selector=f"coral.dev/robot={robot}").items
        return {p.metadata.labels["coral.dev/component"]: p.metadata.uid for p in pods}

    def events(self, reason: str) -> list[str]:
        try:
            items = self.core.list_namespaced_event(
                self.namespace, field_selector=f"involvedObject.name={self.name},reason={reason}"
            ).items
        except ApiException:
            return []
        return [e.message for e in items]


def instance_ready(item: dict[str, Any]) -> bool:
    generation = item["metadata"].get("generation")
    for condition in (item.get("status") or {}).get("conditions") or []:
        if condition["type"] == "Ready":
            return condition["status"] == "True" and condition.get("observedGeneration") == generation
    return False


def settled(fleet: Fleet, count: int) -> bool:
    """Ready for the current generation with every robot counted ready and the rollout complete."""
    body = fleet.system()
    status = body.get("status") or {}
    generation = body["metadata"]["generation"]
    ready = next((c for c in status.get("conditions") or [] if c["type"] == "Ready"), {})
    return (
        status.get("observedGeneration") == generation
        and ready.get("status") == "True"
        and ready.get("observedGeneration") == generation
        and (status.get("robots") or {}).get("ready") == count
        and bool((status.get("rollout") or {}).get("complete"))
    )


def rollout_complete(fleet: Fleet) -> bool:
    """`status.rollout.complete` computed from the current generation of the spec."""
    body = fleet.system()
    status = body.get("status") or {}
    return status.get("observedGeneration") == body["metadata"]["generation"] and bool(
        (status.get("rollout") or {}).get("complete")
    )


def wait_settled(fleet: Fleet, count: int, timeout: float = 120) -> None:
    wait_for(
        lambda: settled(fleet, count),
        timeout=timeout,
        interval=0.5,
        message=lambda: f"{count} robots ready and the rollout complete; rollout={fleet.rollout()}",
    )


def rolled_back_and_ready(fleet: Fleet, count: int) -> bool:
    """After an undo: every robot Ready, the rollout complete, and the system Stalled (RolledBack)."""
    body = fleet.system()
    status = body.get("status") or {}
    rollout = status.get("rollout") or {}
    stalled = next((c for c in status.get("conditions") or [] if c["type"] == "Stalled"), {})
    return (
        status.get("observedGeneration") == body["metadata"]["generation"]
        and (status.get("robots") or {}).get("ready") == count
        and bool(rollout.get("complete") and rollout.get("rolledBack"))
        and (stalled.get("status"), stalled.get("reason")) == ("True", "RolledBack")
    )
