"""What the hostile-tenant tests of issue 47 share: one operator for the module, in a memory cgroup of
the chart's limit as in its pod, serving the module's namespaces; and, for most of them, a healthy
system in a namespace of its own that must stay Ready, with the same pods, while the others attack.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

import pytest
from coral_api import Coral, condition, fleet_mission, is_current_and_true
from coral_core.names import GROUP, VERSION
from coral_testbed.cluster import memorycgroup
from coral_testbed.waiting import wait_for
from fixtures.confined import ConfinedOperator
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

# How long an attack may take to end in a clear status.
CLEAR_WITHIN_S = 60
# The mark of every module that starts an operator here.
NEEDS_A_MEMORY_CGROUP = pytest.mark.skipif(
    memorycgroup.available() is not None, reason=str(memorycgroup.available())
)


@contextmanager
def confined_operator(
    cluster: Any, namespaces: list[str], log: Path, env: dict[str, str] | None = None
) -> Iterator[ConfinedOperator]:
    """The operator serving `namespaces` under the chart's memory limit; on the way out it is stopped
    and the namespaces are deleted."""
    operator = ConfinedOperator.start(cluster, namespaces, log, env)
    try:
        yield operator
    finally:
        operator.stop()
        core = k8s.CoreV1Api(cluster.api_client)
        for namespace in namespaces:
            core.delete_namespace(namespace)


@dataclass
class HostileStage:
    """The operator serving the module's namespaces, and the system `healthy` of namespace `healthy`,
    on the one robot of `fleet`, which must stay Ready with the pods `healthy_pods` throughout."""

    cluster: Any
    operator: ConfinedOperator
    fleet: str
    healthy: str
    healthy_pods: dict[str, str]

    @classmethod
    @contextmanager
    def serving(
        cls, cluster: Any, namespaces: list[str], healthy: str, log: Path, **fields: Any
    ) -> Iterator[Self]:
        """Adds a robot of a new fleet, starts the operator for `namespaces` (`healthy` among them) and
        waits for the healthy system to be Ready; `fields` are the module's own. The policy is the
        shipped default opened for what the fleet example needs, as an administrator running ROS 2
        over DDS would: the host network, and the robot's bags for its bag player. On the way out the
        operator is stopped, the namespaces are deleted and the robot is removed."""
        env = {
            "CORAL_POLICY_HOST_NETWORK_NAMESPACES": ",".join(namespaces),
            "CORAL_POLICY_HOST_PATHS": ",".join(f"{n}=/var/lib/coral/bags" for n in namespaces),
        }
        fleet = f"f{uuid.uuid4().hex[:8]}"
        robot = f"r{uuid.uuid4().hex[:5]}-1"
        cluster.add_robots([robot], {"fleet": fleet})
        try:
            with confined_operator(cluster, namespaces, log, env) as operator:
                stage = cls(cluster, operator, fleet, healthy, {}, **fields)
                stage.coral(healthy).create_system(fleet_mission("healthy", fleet))
                stage.wait_ready(healthy, "healthy")
                stage.healthy_pods = stage.pods_now()
                yield stage
        finally:
            cluster.remove_robots([robot])

    def coral(self, namespace: str) -> Coral:
        return Coral(self.cluster.api_client, namespace)

    def logs(self) -> str:
        return self.operator.logs()

    def wait_ready(self, namespace: str, name: str) -> None:
        wait_for(
            lambda: is_current_and_true(self.coral(namespace).system(name), "Ready"),
            timeout=90,
            message=lambda: f"the system {name} to become Ready; operator log:\n{self.logs()[-3000:]}",
        )

    def stalled(self, namespace: str, name: str) -> dict[str, Any]:
        """The system's Stalled condition once it is True, which the operator made no instance of."""
        coral = self.coral(namespace)
        system = wait_for(
            lambda: is_current_and_true(coral.system(name), "Stalled") and coral.system(name),
            timeout=CLEAR_WITHIN_S,
            interval=0.3,
            message=lambda: f"{name} to be Stalled; operator log:\n{self.logs()[-3000:]}",
        )
        assert not [i for i in coral.instances().values() if i["spec"]["system"] == name]
        return condition(system, "Stalled")

    def pods_now(self) -> dict[str, str]:
        """The healthy namespace's pods, by name, with their uids."""
        return {n: p.metadata.uid for n, p in self.coral(self.healthy).pods().items()}

    def assert_still_serving(self) -> None:
        """The operator is the same process, was never OOM-killed, stayed under the chart's limit and
        logged no traceback, and the healthy system kept its Ready and its pods."""
        self.operator.assert_serving()
        assert is_current_and_true(self.coral(self.healthy).system("healthy"), "Ready")
        assert self.pods_now() == self.healthy_pods


def refused_at_admission(coral: Coral, manifest: dict[str, Any]) -> str:
    """The API server's message refusing to create the system `manifest` as invalid."""
    with pytest.raises(ApiException) as refused:
        coral.create_system(manifest)
    assert refused.value.status == 422
    return json.loads(refused.value.body)["message"]


def forge_ready(api: k8s.CustomObjectsApi, instance: dict[str, Any], reason: str, **status: Any) -> None:
    """Writes Ready=True for `reason` at the instance's generation into its status, with the other
    `status` fields, as whoever `api` speaks for."""
    forged = {
        "type": "Ready",
        "status": "True",
        "reason": reason,
        "message": "forged by the executor",
        "observedGeneration": instance["metadata"]["generation"],
        "lastTransitionTime": "2026-01-01T00:00:00Z",
    }
    api.patch_namespaced_custom_object_status(
        GROUP,
        VERSION,
        instance["metadata"]["namespace"],
        "coralinstances",
        instance["metadata"]["name"],
        {"status": {"conditions": [forged], **status}},
        _content_type="application/merge-patch+json",
    )
