"""What the kind tests of this folder share: the cluster's name, its robots and its handle."""

from __future__ import annotations

from dataclasses import dataclass

from coral_testbed.cluster.client import Cluster
from coral_testbed.kind import clusters

NAME = "coral-test"
ROBOTS = {"kind-robot-1": {"coral.dev/model": "kind"}, "kind-robot-2": {"coral.dev/model": "kind"}}
MISSIONS_NAMESPACE = "kind-missions"
"""Where `kind_missions`' operator serves the tests' CoralSystems."""


@dataclass(frozen=True)
class KindCluster:
    running: clusters.Running
    cluster: Cluster
    """kubectl, helm and the API client against the kind cluster."""
