"""A registry a kind robot cannot reach, for the init step that owns the plugin folder.

Issue 50: with the registry down, the pods said `ImagePullBackOff` for that init step (it runs the
operator's helper image, the chart's `helperImage`), while the CoralInstance said only
`HealthTimeout`. Here the chart's helper image is named at the registry's own address (a name the
robot never pulled, with no other host to fall back on) and the robot's connections to the registry
are refused inside its own network namespace (containerd's own error: the connection is refused),
so every component pod's first container cannot be pulled. The instance must say `ImagePullFailed`
with the kubelet's message within 30 s, without being Stalled; then the robot's way to the registry
is opened again, the kubelet's back-off pulls the image, the mission runs, and the instance tells
the recovery in a Normal Event (`pullfailures`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
from coral_testbed.cluster import operatorchart
from coral_testbed.kind.missions import KindMissionStack

from . import pullfailures

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(600)]


@pytest.fixture
def helper_image(kind_operator: KindMissionStack) -> Iterator[str]:
    """The operator's image named at the registry's own address (no robot has it under that name),
    made the chart's helper image."""
    repository, tag = operatorchart.operator_image()
    path = repository.removeprefix(operatorchart.ROBOT_REGISTRY + "/")
    image = f"{kind_operator.running.registry_address}/{path}:{tag}"
    with pullfailures.chart_helper_image(kind_operator, image):
        yield image


@pytest.fixture
def unreachable_registry(kind_operator: KindMissionStack, helper_image: str) -> Iterator[Callable[[], None]]:
    """The robot cut off from the registry; call the result to let it reach the registry again."""
    with pullfailures.registry_refused(kind_operator.running, pullfailures.ROBOT) as reopen:
        yield reopen


def test_an_unreachable_registry_for_the_plugin_folder_step_is_named_and_its_recovery_told(
    kind_operator: KindMissionStack,
    helper_image: str,
    unreachable_registry: Callable[[], None],
    ros_env: dict[str, str],
) -> None:
    pullfailures.named_then_recovered(
        kind_operator,
        robot=pullfailures.ROBOT,
        domain=int(ros_env["ROS_DOMAIN_ID"]),
        image=helper_image,
        cause="connection refused",
        cure=unreachable_registry,
    )
