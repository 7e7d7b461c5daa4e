"""A registry a robot cannot reach, for the init step that owns the plugin folder, on a real robot.

Issue 50: with the registry down, the pods said `ImagePullBackOff` for that init step (it runs the
operator's helper image), while the CoralInstance said only `HealthTimeout`. Here the helper image
is named at a port of the robot's loopback where nothing listens (containerd's own error: the
connection is refused), so every component pod's first container cannot be pulled. The instance
must say `ImagePullFailed` with the kubelet's message within 30 s, without being Stalled; then the
registry is offered at that port inside the robot, the kubelet's back-off pulls the image, the
mission runs, and the instance tells the recovery in a Normal Event.
"""

from __future__ import annotations

import contextlib
import shutil
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from coral_operator.planning.pods import FOLDERS_OWNER
from coral_testbed.cluster import Cluster, operatorchart, realrobots, uplink
from coral_testbed.waiting import wait_for
from fixtures.operator import OperatorProcess
from fixtures.robots import REAL_ROBOT_MARKS
from kubernetes import client as k8s

from . import realsystems as rs
from .conftest import first_real_robot

pytestmark = [*REAL_ROBOT_MARKS, pytest.mark.timeout(480)]

SYSTEM = "unpulled"
TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Count count="{count}"/>
  </BehaviorTree>
</root>
"""


@pytest.fixture
def silent_port(real_robots: realrobots.RealRobots) -> Iterator[int]:
    """A port of the first robot's loopback that nothing listens on (the kernel chose it free), which
    the robot's containerd knows as a plain-HTTP registry, as it knows the session's."""
    layout = real_robots.layout(first_real_robot(real_robots))
    probe = uplink.listen_inside(str(layout.link.netns_path), 0)
    port = probe.getsockname()[1]
    probe.close()
    hosts = layout.registry_hosts_dir / f"127.0.0.1:{port}"
    hosts.mkdir(parents=True)
    (hosts / "hosts.toml").write_text(f'server = "http://127.0.0.1:{port}"\n')
    yield port
    shutil.rmtree(hosts)


@pytest.fixture
def helper_image(silent_port: int) -> str:
    """The operator's image, named at the silent port instead of the registry's name."""
    repository, tag = operatorchart.operator_image()
    return f"127.0.0.1:{silent_port}/{repository.removeprefix(operatorchart.ROBOT_REGISTRY + '/')}:{tag}"


@pytest.fixture
def operator_env(helper_image: str) -> dict[str, str]:
    return {"CORAL_HELPER_IMAGE": helper_image}


@pytest.fixture
def offer_registry(
    real_robots: realrobots.RealRobots, silent_port: int, image_registry: str
) -> Iterator[Callable[[], None]]:
    """Call it to offer the session's registry at the silent port inside the robot, until the test ends."""
    netns = str(real_robots.layout(first_real_robot(real_robots)).link.netns_path)
    host_port = int(image_registry.rpartition(":")[2])
    with contextlib.ExitStack() as stack:
        yield lambda: stack.enter_context(uplink.offered_inside(netns, silent_port, host_port))


def _events(core: k8s.CoreV1Api, namespace: str, instance: str) -> list[Any]:
    selector = f"involvedObject.name={instance},involvedObject.kind=CoralInstance"
    return core.list_namespaced_event(namespace, field_selector=selector).items


def _pull_failed(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, Any]:
    item = rs.instance(custom, namespace, SYSTEM)
    return item if rs.condition(item, "ComponentsReady").get("reason") == "ImagePullFailed" else {}


def test_an_unreachable_registry_for_the_plugin_folder_step_is_named_and_its_recovery_told(
    cluster: Cluster,
    namespace: str,
    built_images: dict[str, Any],
    real_robots: realrobots.RealRobots,
    coral_operator: OperatorProcess,
    helper_image: str,
    offer_registry: Callable[[], None],
    ros_env: dict[str, str],
) -> None:
    robot = first_real_robot(real_robots)
    core, custom = k8s.CoreV1Api(cluster.api_client), k8s.CustomObjectsApi(cluster.api_client)
    rs.create(custom, namespace, rs.system(SYSTEM, robot, int(ros_env["ROS_DOMAIN_ID"]), TREE))
    wait_for(lambda: rs.pods(core, namespace, SYSTEM), timeout=60, message="the first component pod")
    created = time.monotonic()
    item = wait_for(
        lambda: _pull_failed(custom, namespace),
        timeout=30,
        interval=0.5,
        message=lambda: f"ImagePullFailed within 30 s: {rs.instance(custom, namespace, SYSTEM)}",
    )
    components = rs.condition(item, "ComponentsReady")
    assert f"container {FOLDERS_OWNER}:" in components["message"], components
    assert helper_image in components["message"], "the kubelet's message names the image"
    assert rs.condition(item, "Stalled")["status"] == "False", "the kubelet keeps trying"
    instance = item["metadata"]["name"]
    warned = wait_for(
        lambda: [e for e in _events(core, namespace, instance) if e.reason == "ImagePullFailed"],
        timeout=30,
        message="a Warning Event on the instance",
    )
    assert warned[0].type == "Warning" and helper_image in warned[0].message
    print(f"ImagePullFailed on the instance {time.monotonic() - created:.1f} s after its first pod")

    offer_registry()
    restored = time.monotonic()
    wait_for(
        lambda: rs.with_root(custom, namespace, SYSTEM, "SUCCESS"),
        timeout=360,
        interval=1,
        message=lambda: (
            f"the mission to run once the image can be pulled: {rs.instance(custom, namespace, SYSTEM)}"
        ),
    )
    print(f"the mission succeeded {time.monotonic() - restored:.1f} s after the registry came back")
    # The executor writes the root's SUCCESS itself; the operator's next pass tells ComponentsReady.
    wait_for(
        lambda: rs.condition(rs.instance(custom, namespace, SYSTEM), "ComponentsReady").get("status")
        == "True",
        timeout=30,
        interval=0.5,
        message=lambda: f"ComponentsReady=True after the pull: {rs.instance(custom, namespace, SYSTEM)}",
    )
    told = wait_for(
        lambda: [e for e in _events(core, namespace, instance) if e.reason == "Recovered"],
        timeout=30,
        message="a Normal Event telling the recovery",
    )
    assert told[0].type == "Normal" and told[0].message.startswith("No longer ImagePullFailed"), told[0]
    rs.delete(custom, namespace, SYSTEM)
