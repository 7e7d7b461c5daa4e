"""Manifests shared by the control-plane acceptance tests."""

from __future__ import annotations

import yaml
from fixtures.tolerations import robot_down_tolerations

ROBOT_TOLERATIONS = robot_down_tolerations()


def robot_pod(name: str, robot: str, tolerations: list[dict[str, object]] | None = None) -> str:
    """A Pod pinned to `robot` by nodeSelector, as YAML for `kubectl apply -f -`."""
    return yaml.safe_dump(
        {
            "apiVersion": "v1",
            "kind": "Pod",
            "metadata": {"name": name},
            "spec": {
                "nodeSelector": {"coral.dev/robot": robot},
                "tolerations": ROBOT_TOLERATIONS if tolerations is None else tolerations,
                "containers": [{"name": "main", "image": "registry.k8s.io/pause:3.10"}],
            },
        }
    )
