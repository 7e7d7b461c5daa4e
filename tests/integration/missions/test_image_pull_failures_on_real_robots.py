"""A registry a robot cannot reach, for the init step that owns the plugin folder, on a real robot.

Issue 50: with the registry down, the pods said `ImagePullBackOff` for that init step (it runs the
operator's helper image), while the CoralInstance said only `HealthTimeout`. Here the helper image
is named at a port of the robot's loopback where nothing listens (containerd's own error: the
connection is refused), so every component pod's first container cannot be pulled. The instance
must say `ImagePullFailed` with the kubelet's message within 30 s, without being Stalled; then the
registry is offered at that port inside the robot, the kubelet's back-off pulls the image, the
mission runs, and the instance tells the recovery in a Normal Event (`pullfailures`).
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from coral_testbed.cluster import Cluster, operatorchart, realrobots, uplink
from fixtures.operator import OperatorProcess
from fixtures.robots import REAL_ROBOT_MARKS
from kubernetes import client as k8s

from . import pullfailures
from .conftest import first_real_robot

pytestmark = [*REAL_ROBOT_MARKS, pytest.mark.timeout(480)]


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
    pullfailures.named_then_recovered(
        core=k8s.CoreV1Api(cluster.api_client),
        custom=k8s.CustomObjectsApi(cluster.api_client),
        namespace=namespace,
        robot=first_real_robot(real_robots),
        domain=int(ros_env["ROS_DOMAIN_ID"]),
        image=helper_image,
        cause="connection refused",
        cure=offer_registry,
    )
