"""Host paths on a kind robot: owned per namespace, no way out through a planted link, no user image
as root (issue 47, items 1 to 3).

The attack as it succeeded before: a pod of namespace A planted symbolic links in a folder under
`/var/lib/coral` (to the robot's `/etc`, and into namespace B's folder); a system of A then mounted
the link's path, which passed the policy's string check, and containerd followed it: `/etc` was
read and a file written into B's folder. And the step handing the plugin folder to the components'
user ran `chown` from the component's own image as root.

Now each namespace mounts only inside its own data subtree `/var/lib/coral/data/<namespace>`, as
that folder plus a `subPath`, which the kubelet opens without following a link out of the volume.
The chart's operator (`kind_missions`, in its pod under the chart's memory limit) serves A and B
besides its own namespace, by `helm upgrade` of its `watchNamespaces` for this module and back
after it; B runs a healthy system on a kind robot writing into its own folder throughout. The
robot's files are the node container's: the tests look at them inside the node, as someone logged
into the robot would.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from coral_core.component_image import COMPONENT_UID
from coral_testbed import images
from coral_testbed.cluster import operatorchart
from coral_testbed.images import catalog
from coral_testbed.kind import faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.missions.stack import MissionView
from coral_testbed.waiting import holds_for, wait_for
from fixtures.cluster import create_test_namespace
from fixtures.conditions import condition, is_current_and_true
from missions import realsystems as rs

from .fleet import stops_on_sigterm

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

ROBOT = "relay-worker"
DATA_ROOT = "/var/lib/coral/data"
TREE = '<root BTCPP_format="4"><BehaviorTree ID="Main"><AlwaysSuccess/></BehaviorTree></root>'
SECRET = "data of namespace b"


@dataclass
class Stage:
    missions: KindMissionStack
    a: MissionView
    b: MissionView
    operator_uid: str
    """The operator's pod serving A and B: the same one must serve them throughout."""

    def logs(self) -> str:
        return self.missions.operator_log_tail(5000)

    def on_robot(self, *script: str) -> Any:
        """`sh -c` of `script` on the robot, inside its node container; the finished process."""
        node = faults.node_of(self.missions.running, ROBOT)
        return self.missions.running.engine.docker("exec", node, "sh", "-c", " ".join(script), check=False)

    def holds(self, test: str) -> bool:
        """Whether `test ...` on the robot succeeds (a path exists, is a link...)."""
        return self.on_robot("test", test).returncode == 0

    def owner(self, path: str) -> int:
        return int(self.on_robot("stat", "-c", "%u", path).stdout.strip())

    def describe(self, view: MissionView) -> str:
        """The namespace's instances' conditions and pods' container states, for failure messages."""
        lines = []
        for instance in view.instances():
            conditions = (instance.get("status") or {}).get("conditions") or []
            lines.append(
                f"instance {instance['metadata']['name']}: "
                f"{[(c['type'], c['status'], c['message'][:300]) for c in conditions]}"
            )
        for pod in view.core.list_namespaced_pod(view.namespace).items:
            statuses = [*(pod.status.init_container_statuses or []), *(pod.status.container_statuses or [])]
            states = [(s.name, s.state.to_dict()) for s in statuses]
            lines.append(f"pod {pod.metadata.name}: {pod.status.phase} {states}")
        return "\n".join(lines) + f"\noperator log:\n{self.logs()[-2000:]}"

    def system(self, view: MissionView, name: str) -> dict[str, Any] | None:
        listed = view.custom.list_namespaced_custom_object(
            rs.GROUP, rs.VERSION, view.namespace, "coralsystems"
        )
        return next((s for s in listed["items"] if s["metadata"]["name"] == name), None)

    def deploy(self, view: MissionView, name: str, script: str, host_paths: list[dict[str, Any]]) -> None:
        """A one-driver system on the robot: the driver (the runtime image, non-root) runs `script`
        with `host_paths` mounted; the executor only waits."""
        runtime = catalog.by_name()["runtime"].reference
        driver = {
            "name": "driver",
            "image": runtime,
            "command": ["sh", "-c", stops_on_sigterm(script)],
            "hostPaths": host_paths,
        }
        rs.create(
            view.custom,
            view.namespace,
            {
                "apiVersion": f"{rs.GROUP}/{rs.VERSION}",
                "kind": "CoralSystem",
                "metadata": {"name": name},
                "spec": {
                    "robots": {"matchLabels": {"coral.dev/robot": ROBOT}},
                    "ros": {"network": "Pod"},
                    "parameters": {"inline": ""},
                    "tree": {"inline": TREE},
                    "drivers": [driver],
                    "executors": [
                        {
                            "name": "executor",
                            "image": runtime,
                            "command": ["sh", "-c", stops_on_sigterm("sleep infinity")],
                        }
                    ],
                },
            },
        )

    def assert_still_serving(self) -> None:
        """The same operator pod, never restarted nor OOM-killed under the chart's limit, no
        traceback; B's healthy system Ready and still writing."""
        pods = operatorchart.operator_pods(self.missions.cluster.api_client, self.missions.release)
        assert [p.metadata.uid for p in pods] == [self.operator_uid], self.logs()
        status = pods[0].status.container_statuses[0]
        killed = status.last_state.terminated
        assert status.restart_count == 0 and killed is None, (status, self.logs())
        assert "Traceback" not in self.logs(), self.logs()
        assert is_current_and_true(self.system(self.b, "healthy"), "Ready")


def _upgrade(missions: KindMissionStack, release: operatorchart.Release) -> str:
    """`helm upgrade` of the chart's operator to `release`; the uid of its new pod."""
    assert missions.cluster.bin_dir is not None
    helm = missions.cluster.bin_dir / "helm"
    pod = operatorchart.upgrade(missions.cluster.api_client, helm, missions.cluster.env(), release)
    return str(pod.metadata.uid)


@pytest.fixture(scope="module")
def stage(kind_missions: KindMissionStack) -> Iterator[Stage]:
    missions = kind_missions
    images.build(["runtime"], registry_address=missions.running.registry_address)
    core = missions.core
    a, b = create_test_namespace(core, "tenant-a"), create_test_namespace(core, "tenant-b")
    release = missions.release
    watching = dataclasses.replace(release, watch_namespaces=(*release.watch_namespaces, a, b))
    views = [MissionView(missions.cluster, a), MissionView(missions.cluster, b)]
    try:
        stage = Stage(missions, *views, operator_uid=_upgrade(missions, watching))
        # B's healthy system keeps writing into its own folder, handed to its user by the helper.
        stage.deploy(
            stage.b,
            "healthy",
            f"echo '{SECRET}' > /data/secret && while true; do date > /data/alive; sleep 1; done",
            [{"hostPath": f"{DATA_ROOT}/{b}/mine", "mountPath": "/data", "readOnly": False}],
        )
        wait_for(
            lambda: is_current_and_true(stage.system(stage.b, "healthy"), "Ready"),
            timeout=420,
            interval=1,
            message=lambda: f"B's healthy system to become Ready:\n{stage.describe(stage.b)}",
        )
        yield stage
    finally:
        for view in views:
            view.delete_systems(timeout=180)
        _upgrade(missions, release)
        for namespace in (a, b):
            core.delete_namespace(namespace)


def _instance(view: MissionView, system: str) -> dict[str, Any] | None:
    return rs.instance(view.custom, view.namespace, system) or None


def _refused(stage: Stage, system: str) -> dict[str, Any]:
    """A's system's instance once ComponentsReady says the kubelet refused a container."""

    def seen() -> dict[str, Any] | None:
        instance = _instance(stage.a, system)
        refused = instance and condition(instance, "ComponentsReady").get("reason") == "ContainerRefused"
        return instance if refused else None

    return wait_for(
        seen,
        timeout=180,
        interval=1,
        message=lambda: f"{system} refused by the kubelet:\n{stage.describe(stage.a)}",
    )


def test_links_planted_by_a_tenant_lead_nowhere_outside_its_folder(stage: Stage) -> None:
    a, b = stage.a.namespace, stage.b.namespace
    # A pod of A, with every right a tenant has on its own folder, plants the links.
    stage.deploy(
        stage.a,
        "planter",
        f"ln -sfn /etc /plant/etc && ln -sfn {DATA_ROOT}/{b}/mine /plant/b && sleep infinity",
        [{"hostPath": f"{DATA_ROOT}/{a}/plant", "mountPath": "/plant", "readOnly": False}],
    )
    planted = f"{DATA_ROOT}/{a}/plant"
    wait_for(
        lambda: stage.holds(f"-L {planted}/etc") and stage.holds(f"-L {planted}/b"),
        timeout=300,
        interval=1,
        message=lambda: f"the links planted:\n{stage.describe(stage.a)}",
    )
    # The planter's folder was handed over as a folder of A's user, not followed anywhere.
    assert stage.owner(planted) == COMPONENT_UID

    # Both systems pass the policy (the paths are inside A's folder) and reach the robot...
    for name, link, target in (("reader", "etc", "/stolen"), ("writer", "b", "/victim")):
        script = "cat /stolen/hostname /stolen/shadow; echo pwned > /victim/pwned; sleep infinity"
        mount = {"hostPath": f"{planted}/{link}", "mountPath": target, "readOnly": False}
        stage.deploy(stage.a, name, script, [mount])
    # ...where the kubelet refuses the containers, and the instance says so in its words.
    for name in ("reader", "writer"):
        instance = _refused(stage, name)
        message = condition(instance, "ComponentsReady")["message"]
        assert "driver: CreateContainerConfigError: failed to prepare subPath" in message, message
        stalled = condition(instance, "Stalled")
        assert (stalled["status"], stalled["reason"]) == ("True", "ContainerRefused"), stalled

    # Nothing of /etc or B's folder was read or written: no driver container of A ever started.
    pods = [
        p
        for p in stage.a.core.list_namespaced_pod(a).items
        if p.metadata.labels.get("coral.dev/system") != "planter"
    ]
    for pod in pods:
        assert not any(s.state.running or s.state.terminated for s in pod.status.container_statuses or [])
    holds_for(
        lambda: not stage.holds(f"-e {DATA_ROOT}/{b}/mine/pwned"),
        duration=5,
        message="no file of A in B's folder",
    )
    assert stage.on_robot("cat", f"{DATA_ROOT}/{b}/mine/secret").stdout.strip() == SECRET
    stage.assert_still_serving()


def test_a_tenant_asking_for_another_namespaces_folder_is_refused_by_the_policy(stage: Stage) -> None:
    a, b = stage.a.namespace, stage.b.namespace
    stage.deploy(
        stage.a,
        "neighbour",
        "sleep infinity",
        [{"hostPath": f"{DATA_ROOT}/{a}/../{b}/mine", "mountPath": "/victim"}],
    )
    system = wait_for(
        lambda: is_current_and_true(found := stage.system(stage.a, "neighbour"), "Stalled") and found,
        timeout=60,
        message=lambda: f"the system to be refused; operator log:\n{stage.logs()[-3000:]}",
    )
    stalled = condition(system, "Stalled")
    assert stalled["reason"] == "PolicyDenied"
    assert (
        f"spec.drivers[0] (driver): hostPaths[0].hostPath: host path {DATA_ROOT}/{b}/mine is outside the "
        f"folders namespace {a} may mount ({DATA_ROOT}/{a})"
    ) in stalled["message"]
    assert _instance(stage.a, "neighbour") is None
    stage.assert_still_serving()


def test_the_ownership_step_never_runs_a_user_image_as_root(stage: Stage) -> None:
    b = stage.b.namespace
    runtime = catalog.by_name()["runtime"].reference
    helper = ":".join(operatorchart.operator_image())
    for pod in stage.b.core.list_namespaced_pod(b).items:
        for container in [*(pod.spec.init_containers or []), *pod.spec.containers]:
            root = container.security_context and container.security_context.run_as_user == 0
            if root:
                assert container.image == helper, (pod.metadata.name, container.image)
            if container.image == runtime:
                assert not root and container.security_context.run_as_non_root, container.name
    # On the robot: the plugin folder and B's data folder belong to the components' user, and
    # nothing in them is setuid.
    for folder in (f"/var/lib/coral/plugins/{b}/healthy", f"{DATA_ROOT}/{b}/mine"):
        assert stage.owner(folder) == COMPONENT_UID, folder
        setuid = stage.on_robot("find", folder, "!", "-type", "l", "-perm", "/6000").stdout.split()
        assert not setuid, setuid
    stage.assert_still_serving()
