"""CoralInstances written by others than the operator: a lie does not stick, a hand-made one runs nothing.

Issue 47, items 5 and 6. With its own token an executor wrote `Ready=True` and an unparsable
`status.tree.updatedAt`; every operator pass of that instance then raised before writing, so the
forged Ready stuck. And a user who may create CoralInstances but not pods got a privileged,
host-network pod with `/` mounted, or a pod running as another system's executor account.

One operator (in a memory cgroup of the chart's limit) serves two namespaces for the module:
`attacks` (two systems, `mine` and `other`, and a ServiceAccount whose Role allows CoralInstances and
nothing else) and `healthy` (a system that must stay Ready with the same pods throughout). The
policy is the shipped default opened only for the host network and the robot's bags, as an
administrator running the fleet example would.
"""

from __future__ import annotations

import copy
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from coral_api import client_as, condition, executor_client, fleet_mission, is_current_and_true
from coral_core import names
from coral_core.names import GROUP, VERSION
from coral_testbed.waiting import holds_for, wait_for
from fixtures.cluster import create_test_namespace
from hostile import NEEDS_A_MEMORY_CGROUP, HostileStage, forge_ready
from kubernetes import client as k8s

pytestmark = [pytest.mark.cluster, pytest.mark.slow, NEEDS_A_MEMORY_CGROUP]

# "Within seconds": the operator's passes of one instance are spaced by tens of milliseconds.
OVERWRITTEN_WITHIN_S = 15
REPORTED_WITHIN_S = 30
# How long a hand-made instance is watched for a pod that must never come.
NO_POD_FOR_S = 8
MERGE = "application/merge-patch+json"
WRITER = "instance-writer"


@dataclass
class Stage(HostileStage):
    attacks: str


def _instance_writer(cluster: Any, namespace: str) -> None:
    """A ServiceAccount that may do anything with CoralInstances of the namespace, and nothing else."""
    core, rbac = k8s.CoreV1Api(cluster.api_client), k8s.RbacAuthorizationV1Api(cluster.api_client)
    core.create_namespaced_service_account(namespace, {"metadata": {"name": WRITER}})
    rule = {"apiGroups": [GROUP], "resources": ["coralinstances"], "verbs": ["*"]}
    rbac.create_namespaced_role(namespace, {"metadata": {"name": WRITER}, "rules": [rule]})
    rbac.create_namespaced_role_binding(
        namespace,
        {
            "metadata": {"name": WRITER},
            "roleRef": {"apiGroup": "rbac.authorization.k8s.io", "kind": "Role", "name": WRITER},
            "subjects": [{"kind": "ServiceAccount", "name": WRITER, "namespace": namespace}],
        },
    )


@pytest.fixture(scope="module")
def stage(cluster: Any, coral_crds: None, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Stage]:
    core = k8s.CoreV1Api(cluster.api_client)
    attacks, healthy = create_test_namespace(core, "attacks"), create_test_namespace(core, "healthy")
    log = tmp_path_factory.mktemp("hostile-instances") / "operator.log"
    with Stage.serving(cluster, [attacks, healthy], healthy, log, attacks=attacks) as stage:
        for name in ("mine", "other"):
            stage.coral(attacks).create_system(fleet_mission(name, stage.fleet))
        for name in ("mine", "other"):
            stage.wait_ready(attacks, name)
        _instance_writer(cluster, attacks)
        yield stage


def _own_instance(stage: Stage, system: str) -> dict[str, Any]:
    return next(i for i in stage.coral(stage.attacks).instances().values() if i["spec"]["system"] == system)


def test_a_forged_ready_with_an_unparsable_time_is_overwritten_and_the_field_reported(stage: Stage) -> None:
    instance = _own_instance(stage, "mine")
    name = instance["metadata"]["name"]
    as_executor = k8s.CustomObjectsApi(executor_client(stage.cluster, stage.attacks, name))
    start = time.monotonic()
    forge_ready(as_executor, instance, "Forged", tree={"rootStatus": "RUNNING", "updatedAt": "not a time"})
    coral = stage.coral(stage.attacks)

    def overwritten() -> dict[str, Any] | None:
        current = coral.instances()[name]
        ready = condition(current, "Ready")
        return current if ready.get("reason") not in (None, "Forged") else None

    current = wait_for(
        overwritten,
        timeout=OVERWRITTEN_WITHIN_S,
        interval=0.2,
        message=lambda: f"the forged Ready to be overwritten; operator log:\n{stage.logs()[-3000:]}",
    )
    print(f"forged Ready overwritten after {time.monotonic() - start:.1f} s")
    assert {c["type"] for c in current["status"]["conditions"]} > {"Ready", "Stalled", "TreeHealthy"}
    assert (
        "status.tree.updatedAt: 'not a time' is not an RFC 3339 time"
        in condition(current, "TreeHealthy")["message"]
    )
    # The robot really runs: Ready is the operator's own verdict, at the instance's generation.
    assert is_current_and_true(current, "Ready") and condition(current, "Ready")["reason"] == "Ready"
    stage.assert_still_serving()


def _write_by_hand(stage: Stage, manifest: dict[str, Any]) -> str:
    """Create `manifest` as the ServiceAccount that may write CoralInstances but not pods."""
    client = client_as(stage.cluster, stage.attacks, WRITER)
    assert (
        not k8s.AuthorizationV1Api(client)
        .create_self_subject_access_review(
            {
                "spec": {
                    "resourceAttributes": {"namespace": stage.attacks, "verb": "create", "resource": "pods"}
                }
            }
        )
        .status.allowed
    ), "the writer may not create pods"
    k8s.CustomObjectsApi(client).create_namespaced_custom_object(
        GROUP, VERSION, stage.attacks, "coralinstances", manifest
    )
    return str(manifest["metadata"]["name"])


def _assert_refused(stage: Stage, name: str, fragment: str) -> None:
    """No pod for the instance, ever; Stalled `ForeignInstance` naming the field; a Warning Event."""
    coral, core = stage.coral(stage.attacks), k8s.CoreV1Api(stage.cluster.api_client)

    def reported() -> bool:
        stalled = condition(coral.instances().get(name), "Stalled")
        return stalled.get("reason") == "ForeignInstance" and fragment in stalled.get("message", "")

    wait_for(
        reported,
        timeout=REPORTED_WITHIN_S,
        interval=0.3,
        message=lambda: f"{name} to be reported as not its system's; operator log:\n{stage.logs()[-3000:]}",
    )
    assert condition(coral.instances()[name], "Ready")["status"] == "False"

    def event() -> bool:
        found = core.list_namespaced_event(stage.attacks, field_selector=f"involvedObject.name={name}").items
        return any(e.reason == "ForeignInstance" and e.type == "Warning" for e in found)

    wait_for(event, timeout=REPORTED_WITHIN_S, interval=0.3, message=f"a ForeignInstance Event on {name}")

    def no_pod() -> bool:
        selector = f"{names.LABEL_INSTANCE}={name}"
        return not core.list_namespaced_pod(stage.attacks, label_selector=selector).items

    holds_for(no_pod, duration=NO_POD_FOR_S, message=f"no pod built for {name}")


def test_a_privileged_instance_written_by_hand_for_an_existing_system_gets_no_pod(stage: Stage) -> None:
    legit = _own_instance(stage, "mine")
    spec = copy.deepcopy(legit["spec"])
    spec.setdefault("ros", {})["network"] = "Host"
    spec["drivers"][0] |= {"privileged": True, "hostPaths": [{"hostPath": "/", "mountPath": "/host"}]}
    name = _write_by_hand(
        stage,
        {
            "apiVersion": f"{GROUP}/{VERSION}",
            "kind": "CoralInstance",
            "metadata": {"name": f"root-{uuid.uuid4().hex[:6]}"},
            "spec": spec,
        },
    )
    _assert_refused(stage, name, "metadata.ownerReferences: no controller")
    assert is_current_and_true(stage.coral(stage.attacks).system("mine"), "Ready"), "mine is still served"
    stage.assert_still_serving()


def test_an_instance_naming_another_system_gets_no_pod(stage: Stage) -> None:
    """It would have run as `coral-executor-other`, and its executor could have written `other`'s
    instances; it copies `mine`'s owner, which the API server accepts from anyone."""
    legit = _own_instance(stage, "mine")
    other = stage.coral(stage.attacks).system("other")
    assert other is not None
    name = _write_by_hand(
        stage,
        {
            "apiVersion": f"{GROUP}/{VERSION}",
            "kind": "CoralInstance",
            "metadata": {
                "name": f"other-{uuid.uuid4().hex[:6]}",
                "ownerReferences": legit["metadata"]["ownerReferences"],
            },
            "spec": {**copy.deepcopy(legit["spec"]), "system": "other"},
        },
    )
    _assert_refused(stage, name, "not CoralSystem other")
    for system in ("mine", "other"):
        assert is_current_and_true(stage.coral(stage.attacks).system(system), "Ready"), f"{system} is served"
    stage.assert_still_serving()
