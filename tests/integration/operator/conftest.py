"""The `scenario` fixture: what most operator tests start from, as one fixture instead of six.

Tests that need something else (the chart, one operator for many namespaces) keep
asking for the single fixtures of tests/fixtures/operator.py.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_api import Coral
from coral_testbed.cluster.client import Cluster
from fixtures.operator import OperatorProcess
from scenarios import Scenario


@pytest.fixture
def scenario(
    cluster: Cluster,
    namespace: str,
    coral_operator: OperatorProcess,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Callable[..., Any],
) -> Scenario:
    """The operator serving a fresh namespace, with a fleet label and a robot factory for it."""
    return Scenario(
        cluster=cluster,
        namespace=namespace,
        operator=coral_operator,
        coral=Coral(cluster.api_client, namespace),
        fleet_label=fleet_label,
        wait=wait,
        make_robots=robots,
    )
