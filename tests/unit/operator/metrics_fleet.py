"""A fleet as the operator's indexes hold it, for the metrics tests: one system over N robots (one
of them unreachable with a failed tree), a second system with no instance yet, and a queue."""

from __future__ import annotations

from coral_operator.planning.observed import ObservedInstance, RobotNode, SystemRecord
from coral_operator.reconcile.indexes import ALL_ROBOTS, Indexes, instance_named, instances_of_system

NAMESPACE = "robots"


def _robot(index: int, *, ready: bool = True, reachable: bool = True) -> RobotNode:
    return RobotNode(
        node_name=f"node-{index}", robot=f"r{index}", labels={}, ready=ready, reachable=reachable
    )


def _instance(
    index: int, *, ready: bool, root: str | None, reachable: bool | None = True
) -> ObservedInstance:
    return ObservedInstance(
        name=f"fleet-r{index}",
        robot=f"r{index}",
        spec={},
        revision="1",
        ready=ready,
        root_status=root,
        reachable=reachable,
    )


def _system(name: str, rollout: dict[str, object]) -> SystemRecord:
    return SystemRecord(
        name=name, namespace=NAMESPACE, uid=name, generation=1, spec={}, status={"rollout": rollout}
    )


class Queue:
    def __init__(self, depth: int, wait_s: float) -> None:
        self.depth, self.wait_s = depth, wait_s

    def __len__(self) -> int:
        return self.depth

    def longest_wait_s(self) -> float:
        return self.wait_s


def fleet(robots: int) -> Indexes:
    """Indexes as kopf fills them for one system over `robots` robots: one unreachable robot
    whose tree failed, the rest Ready and RUNNING; a second system with no instance yet."""
    nodes = [_robot(i, reachable=i != 0, ready=i != 0) for i in range(robots)]
    instances = [
        _instance(i, ready=i != 0, root="FAILURE" if i == 0 else "RUNNING", reachable=i != 0)
        for i in range(robots)
    ]
    indexes = Indexes()
    indexes.attach(
        robot_nodes={ALL_ROBOTS: nodes},
        coral_instances={
            instances_of_system(NAMESPACE, "fleet"): instances,
            **{instance_named(NAMESPACE, i.name): [object()] for i in instances},
        },
        coral_systems={
            (NAMESPACE, "fleet"): [
                _system("fleet", {"complete": False, "counts": {"total": robots, "updated": robots - 1}})
            ],
            (NAMESPACE, "empty"): [_system("empty", {})],
        },
    )
    return indexes
