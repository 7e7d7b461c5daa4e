"""Creating many kwok robot Nodes quickly and waiting until kwok reports them Ready.

Uses the testbed's Node manifest (`coral_testbed.cluster.robots.build_robot_node`), so the robots
are the same as in the tests, created by a small thread pool because one POST at a time would make
the set-up of 1000 robots slower than the runs it prepares.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

from coral_testbed.cluster import robots as testbed_robots
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

FLEET_LABEL = "bench.coral.dev/fleet"


def robot_names(count: int) -> list[str]:
    return [f"robot-{i:04d}" for i in range(count)]


def create_robots(api: k8s.ApiClient, names: list[str], workers: int = 8) -> None:
    core = k8s.CoreV1Api(api)

    def create(name: str) -> None:
        body = testbed_robots.build_robot_node(name, {FLEET_LABEL: "bench"})
        try:
            core.create_node(body)
        except ApiException as error:
            if error.status != 409:
                raise

    with ThreadPoolExecutor(max_workers=workers) as pool:
        list(pool.map(create, names))


def wait_robots_ready(api: k8s.ApiClient, count: int, timeout: float) -> None:
    core = k8s.CoreV1Api(api)
    seen = [0]

    def all_ready() -> bool:
        nodes = core.list_node(label_selector=FLEET_LABEL).items
        seen[0] = sum(1 for n in nodes if testbed_robots.ready_status(n) == "True")
        return seen[0] >= count

    wait_for(
        all_ready, timeout=timeout, interval=2.0, message=lambda: f"{count} robots Ready (saw {seen[0]})"
    )
