"""Host paths on a real robot: owned per namespace, no way out through a planted link, no user image
as root (issue 47, items 1 to 3).

The attack as it succeeded before: a pod of namespace A planted symbolic links in a folder under
`/var/lib/coral` (to the robot's `/etc`, and into namespace B's folder); a system of A then mounted
the link's path, which passed the policy's string check, and containerd followed it: `/etc` was
read and a file written into B's folder. And the step handing the plugin folder to the components'
user ran `chown` from the component's own image as root.

Now each namespace mounts only inside its own data subtree `/var/lib/coral/data/<namespace>`, as
that folder plus a `subPath`, which the kubelet opens without following a link out of the volume.
One operator (in a memory cgroup of the chart's limit, as in the other hostile tests) serves A and
B on a real robot; B runs a healthy system writing into its own folder throughout.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from coral_api import Coral, condition, is_current_and_true
from coral_testbed.cluster import operatorchart, realrobots
from coral_testbed.images import catalog
from coral_testbed.waiting import holds_for, wait_for
from fixtures.cluster import create_test_namespace
from fixtures.confined import ConfinedOperator
from fixtures.robots import REAL_ROBOTS
from hostile import NEEDS_A_MEMORY_CGROUP, confined_operator
from kubernetes import client as k8s

pytestmark = [pytest.mark.cluster, pytest.mark.slow, pytest.mark.real_robots, NEEDS_A_MEMORY_CGROUP]

DATA_ROOT = "/var/lib/coral/data"
COMPONENT_UID = 10001
TREE = '<root BTCPP_format="4"><BehaviorTree ID="Main"><AlwaysSuccess/></BehaviorTree></root>'
SECRET = "data of namespace b"


@dataclass
class Stage:
    cluster: Any
    robots: realrobots.RealRobots
    robot: str
    a: str
    b: str
    operator: ConfinedOperator

    def coral(self, namespace: str) -> Coral:
        return Coral(self.cluster.api_client, namespace)

    def logs(self) -> str:
        return self.operator.logs()

    def on_robot(self, path: str) -> Path:
        return self.robots.host_path(self.robot, path)

    def describe(self, namespace: str) -> str:
        """The namespace's instances' conditions and pods' container states, for failure messages."""
        coral = self.coral(namespace)
        lines = []
        for name, instance in coral.instances().items():
            conditions = (instance.get("status") or {}).get("conditions") or []
            lines.append(
                f"instance {name}: {[(c['type'], c['status'], c['message'][:300]) for c in conditions]}"
            )
        for name, pod in coral.pods().items():
            statuses = [*(pod.status.init_container_statuses or []), *(pod.status.container_statuses or [])]
            lines.append(f"pod {name}: {pod.status.phase} {[(s.name, s.state.to_dict()) for s in statuses]}")
        return "\n".join(lines) + f"\noperator log:\n{self.logs()[-2000:]}"

    def deploy(self, namespace: str, name: str, script: str, host_paths: list[dict[str, Any]]) -> None:
        """A one-driver system on the robot: the driver (the runtime image, non-root) runs `script`
        with `host_paths` mounted; the executor only waits."""
        runtime = catalog.by_name()["runtime"].reference
        driver = {
            "name": "driver",
            "image": runtime,
            "command": ["sh", "-c", script],
            "hostPaths": host_paths,
        }
        self.coral(namespace).create_system(
            {
                "apiVersion": "coral.dev/v1alpha1",
                "kind": "CoralSystem",
                "metadata": {"name": name},
                "spec": {
                    "robots": {"matchLabels": {"coral.dev/robot": self.robot}},
                    "ros": {"network": "Pod"},
                    "parameters": {"inline": ""},
                    "tree": {"inline": TREE},
                    "drivers": [driver],
                    "executors": [{"name": "executor", "image": runtime, "command": ["sleep", "infinity"]}],
                },
            }
        )

    def assert_still_serving(self) -> None:
        """Same operator process, never OOM-killed, no traceback, B's healthy system Ready and still
        writing."""
        self.operator.assert_serving()
        assert is_current_and_true(self.coral(self.b).system("healthy"), "Ready")


@pytest.fixture(scope="module")
def stage(
    cluster: Any,
    coral_crds: None,
    real_robots: realrobots.RealRobots,
    built_images: dict[str, Any],
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[Stage]:
    core = k8s.CoreV1Api(cluster.api_client)
    a, b = create_test_namespace(core, "tenant-a"), create_test_namespace(core, "tenant-b")
    log = tmp_path_factory.mktemp("host-paths") / "operator.log"
    with confined_operator(cluster, [a, b], log, {"CORAL_HELPER_IMAGE": _helper_image()}) as operator:
        stage = Stage(cluster, real_robots, REAL_ROBOTS[0], a, b, operator)
        # B's healthy system keeps writing into its own folder, handed to its user by the helper.
        stage.deploy(
            b,
            "healthy",
            f"echo '{SECRET}' > /data/secret && while true; do date > /data/alive; sleep 1; done",
            [{"hostPath": f"{DATA_ROOT}/{b}/mine", "mountPath": "/data", "readOnly": False}],
        )
        wait_for(
            lambda: is_current_and_true(stage.coral(b).system("healthy"), "Ready"),
            timeout=420,
            interval=1,
            message=lambda: f"B's healthy system to become Ready:\n{stage.describe(b)}",
        )
        yield stage


def _helper_image() -> str:
    """The operator's image as robots pull it: what the fixtures and the chart give the ownership step."""
    repository, tag = operatorchart.operator_image()
    return f"{repository}:{tag}"


def _instance(stage: Stage, namespace: str, system: str) -> dict[str, Any] | None:
    found = [i for i in stage.coral(namespace).instances().values() if i["spec"]["system"] == system]
    return found[0] if found else None


def _refused(stage: Stage, namespace: str, system: str) -> dict[str, Any]:
    """The system's instance once ComponentsReady says the kubelet refused a container."""

    def seen() -> dict[str, Any] | None:
        instance = _instance(stage, namespace, system)
        refused = instance and condition(instance, "ComponentsReady").get("reason") == "ContainerRefused"
        return instance if refused else None

    return wait_for(
        seen,
        timeout=180,
        interval=1,
        message=lambda: f"{system} refused by the kubelet:\n{stage.describe(namespace)}",
    )


def test_links_planted_by_a_tenant_lead_nowhere_outside_its_folder(stage: Stage) -> None:
    a, b = stage.a, stage.b
    # A pod of A, with every right a tenant has on its own folder, plants the links.
    stage.deploy(
        a,
        "planter",
        f"ln -sfn /etc /plant/etc && ln -sfn {DATA_ROOT}/{b}/mine /plant/b && sleep infinity",
        [{"hostPath": f"{DATA_ROOT}/{a}/plant", "mountPath": "/plant", "readOnly": False}],
    )
    planted = stage.on_robot(f"{DATA_ROOT}/{a}/plant")
    wait_for(
        lambda: (planted / "etc").is_symlink() and (planted / "b").is_symlink(),
        timeout=300,
        interval=1,
        message=lambda: f"the links planted:\n{stage.describe(a)}",
    )
    # The planter's folder was handed over as a folder of A's user, not followed anywhere.
    assert planted.stat().st_uid == COMPONENT_UID

    # Both systems pass the policy (the paths are inside A's folder) and reach the robot...
    for name, link, target in (("reader", "etc", "/stolen"), ("writer", "b", "/victim")):
        script = "cat /stolen/hostname /stolen/shadow; echo pwned > /victim/pwned; sleep infinity"
        mount = {"hostPath": f"{DATA_ROOT}/{a}/plant/{link}", "mountPath": target, "readOnly": False}
        stage.deploy(a, name, script, [mount])
    # ...where the kubelet refuses the containers, and the instance says so in its words.
    for name in ("reader", "writer"):
        instance = _refused(stage, a, name)
        message = condition(instance, "ComponentsReady")["message"]
        assert "driver: CreateContainerConfigError: failed to prepare subPath" in message, message
        stalled = condition(instance, "Stalled")
        assert (stalled["status"], stalled["reason"]) == ("True", "ContainerRefused"), stalled

    # Nothing of /etc or B's folder was read or written: no driver container of A ever started.
    pods = [
        p for p in stage.coral(a).pods().values() if p.metadata.labels.get("coral.dev/system") != "planter"
    ]
    for pod in pods:
        assert not any(s.state.running or s.state.terminated for s in pod.status.container_statuses or [])
    holds_for(
        lambda: not stage.on_robot(f"{DATA_ROOT}/{b}/mine/pwned").exists(),
        duration=5,
        message="no file of A in B's folder",
    )
    assert stage.on_robot(f"{DATA_ROOT}/{b}/mine/secret").read_text().strip() == SECRET
    stage.assert_still_serving()


def test_a_tenant_asking_for_another_namespaces_folder_is_refused_by_the_policy(stage: Stage) -> None:
    a, b = stage.a, stage.b
    stage.deploy(
        a,
        "neighbour",
        "sleep infinity",
        [{"hostPath": f"{DATA_ROOT}/{a}/../{b}/mine", "mountPath": "/victim"}],
    )
    coral = stage.coral(a)
    system = wait_for(
        lambda: is_current_and_true(coral.system("neighbour"), "Stalled") and coral.system("neighbour"),
        timeout=60,
        message=lambda: f"the system to be refused; operator log:\n{stage.logs()[-3000:]}",
    )
    stalled = condition(system, "Stalled")
    assert stalled["reason"] == "PolicyDenied"
    assert (
        f"spec.drivers[0] (driver): hostPaths[0].hostPath: host path {DATA_ROOT}/{b}/mine is outside the "
        f"folders namespace {a} may mount ({DATA_ROOT}/{a})"
    ) in stalled["message"]
    assert _instance(stage, a, "neighbour") is None
    stage.assert_still_serving()


def test_the_ownership_step_never_runs_a_user_image_as_root(stage: Stage) -> None:
    b = stage.b
    runtime = catalog.by_name()["runtime"].reference
    for pod in stage.coral(b).pods().values():
        for container in [*(pod.spec.init_containers or []), *pod.spec.containers]:
            root = container.security_context and container.security_context.run_as_user == 0
            if root:
                assert container.image == _helper_image(), (pod.metadata.name, container.image)
            if container.image == runtime:
                assert not root and container.security_context.run_as_non_root, container.name
    # On the robot: the plugin folder and B's data folder belong to the components' user, and
    # nothing in them is setuid.
    for folder in (f"/var/lib/coral/plugins/{b}/healthy", f"{DATA_ROOT}/{b}/mine"):
        path = stage.on_robot(folder)
        assert path.stat().st_uid == COMPONENT_UID, folder
        setuid = [p for p in path.rglob("*") if not p.is_symlink() and p.stat().st_mode & 0o6000]
        assert not setuid, setuid
    stage.assert_still_serving()
