"""The scenario most operator tests start from: the operator serving the test's own namespace, a
`Coral` reader over that namespace, and kwok robots carrying a fleet label no other test uses.

Built by the `scenario` fixture (conftest.py); `deploy` applies a system and waits until it is Ready
at its generation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from coral_api import Coral, fleet_mission, is_current_and_true
from coral_testbed.cluster.client import Cluster
from fixtures.operator import OperatorProcess


@dataclass(frozen=True)
class Scenario:
    """One test's operator, namespace, API reader and robots."""

    cluster: Cluster
    namespace: str
    operator: OperatorProcess
    coral: Coral
    fleet_label: str
    wait: Callable[..., Any]
    make_robots: Callable[..., list[str]]
    """The `robots` factory: any labels, for robots outside this test's fleet."""

    def robots(self, count: int, start: int = 1) -> list[str]:
        """`count` new robots in this test's fleet, numbered from `start`."""
        return self.make_robots(count, {"fleet": self.fleet_label}, start=start)

    def mission(self, name: str = "fleet") -> dict[str, Any]:
        """The fleet example as a CoralSystem `name` over this test's robots."""
        return fleet_mission(name, self.fleet_label)

    def deploy(self, manifest: dict[str, Any] | None = None) -> dict[str, Any]:
        """Create `manifest` (the fleet example by default) and return it once Ready at its generation."""
        manifest = manifest or self.mission()
        name = manifest["metadata"]["name"]
        self.coral.create_system(manifest)

        def ready() -> dict[str, Any] | None:
            system = self.coral.system(name)
            return system if is_current_and_true(system, "Ready") else None

        return self.wait(ready, f"the system {name} to become Ready")
