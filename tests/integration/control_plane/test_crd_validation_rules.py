"""Acceptance (b): a CRD's `x-kubernetes-validations` rule rejects a violating object with its message."""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import pytest
import yaml
from coral_testbed.cluster import Cluster, KubectlError

pytestmark = pytest.mark.cluster

RULE_MESSAGE = "minRobots must not exceed maxRobots"


@pytest.fixture
def crd(cluster: Cluster) -> Iterator[tuple[str, str]]:
    """A throwaway namespaced CRD `Fleet` with one CEL rule; yields (resource name, API group)."""
    group = f"g{uuid.uuid4().hex[:8]}.test.coral.dev"
    manifest = {
        "apiVersion": "apiextensions.k8s.io/v1",
        "kind": "CustomResourceDefinition",
        "metadata": {"name": f"fleets.{group}"},
        "spec": {
            "group": group,
            "scope": "Namespaced",
            "names": {"plural": "fleets", "singular": "fleet", "kind": "Fleet"},
            "versions": [
                {
                    "name": "v1",
                    "served": True,
                    "storage": True,
                    "schema": {
                        "openAPIV3Schema": {
                            "type": "object",
                            "properties": {
                                "spec": {
                                    "type": "object",
                                    "properties": {
                                        "minRobots": {"type": "integer"},
                                        "maxRobots": {"type": "integer"},
                                    },
                                    "x-kubernetes-validations": [
                                        {"rule": "self.minRobots <= self.maxRobots", "message": RULE_MESSAGE}
                                    ],
                                }
                            },
                        }
                    },
                }
            ],
        },
    }
    cluster.kubectl("apply", "-f", "-", input=yaml.safe_dump(manifest))
    cluster.kubectl("wait", "--for=condition=Established", f"crd/fleets.{group}", "--timeout=60s", timeout=90)
    yield f"fleets.{group}", group
    cluster.kubectl("delete", "crd", f"fleets.{group}", "--wait=false")


def _fleet(group: str, name: str, low: int, high: int) -> str:
    return yaml.safe_dump(
        {
            "apiVersion": f"{group}/v1",
            "kind": "Fleet",
            "metadata": {"name": name},
            "spec": {"minRobots": low, "maxRobots": high},
        }
    )


def test_object_breaking_the_rule_is_rejected_with_the_rules_message(
    cluster: Cluster, namespace: str, crd: tuple[str, str]
) -> None:
    resource, group = crd
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=_fleet(group, "good", 1, 3))

    with pytest.raises(KubectlError) as rejected:
        cluster.kubectl("apply", "-n", namespace, "-f", "-", input=_fleet(group, "bad", 5, 2))
    assert RULE_MESSAGE in rejected.value.stderr
    assert "Invalid" in rejected.value.stderr

    listed = cluster.kubectl("get", resource, "-n", namespace, "-o", "name").stdout.split()
    assert listed == [f"fleet.{group}/good"]
