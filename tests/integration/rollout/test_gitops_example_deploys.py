"""The GitOps example: `kubectl kustomize` renders it (tree and parameters as hashed ConfigMaps that the
CoralSystem names), the result applies, the fleet comes up, and a commit that edits the tree rolls out
as a new revision."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from coral_testbed.waiting import wait_for
from fleet import Fleet, rollout_complete, wait_settled

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "gitops" / "fleet"


def _render(cluster: Any, folder: Path) -> list[dict[str, Any]]:
    return [doc for doc in yaml.safe_load_all(cluster.kubectl("kustomize", str(folder)).stdout) if doc]


def test_the_example_renders_hashed_config_maps_that_the_system_names(cluster: Any) -> None:
    docs = _render(cluster, EXAMPLE)
    kinds = sorted(d["kind"] for d in docs)
    assert kinds == ["ConfigMap", "ConfigMap", "CoralSystem", "Namespace"]
    maps = {d["metadata"]["name"]: d for d in docs if d["kind"] == "ConfigMap"}
    system = next(d for d in docs if d["kind"] == "CoralSystem")
    tree_ref = system["spec"]["tree"]["configMapRef"]
    params_ref = system["spec"]["parameters"]["configMapRef"]
    assert tree_ref["name"].startswith("patrol-tree-") and tree_ref["name"] in maps
    assert params_ref["name"].startswith("patrol-params-") and params_ref["name"] in maps
    assert "<BehaviorTree" in maps[tree_ref["name"]]["data"][tree_ref["key"]]
    assert all(d["metadata"].get("namespace") == "fleet" for d in docs if d["kind"] != "Namespace")


def _overlay(tmp: Path, namespace: str, fleet_label: str) -> Path:
    """The example as a base, placed in the test's namespace and selecting the test's robots."""
    shutil.copytree(EXAMPLE, tmp / "base")
    overlay = tmp / "overlay"
    overlay.mkdir()
    (overlay / "kustomization.yaml").write_text(
        yaml.safe_dump(
            {
                "apiVersion": "kustomize.config.k8s.io/v1beta1",
                "kind": "Kustomization",
                "namespace": namespace,
                "resources": ["../base"],
                "patches": [
                    {"patch": "$patch: delete\napiVersion: v1\nkind: Namespace\nmetadata:\n  name: fleet\n"},
                    {
                        "target": {"kind": "CoralSystem", "name": "patrol"},
                        "patch": yaml.safe_dump(
                            [
                                {
                                    "op": "replace",
                                    "path": "/spec/robots/matchLabels",
                                    "value": {"fleet": fleet_label},
                                },
                                {"op": "replace", "path": "/spec/rollout/canary/holdSeconds", "value": 2},
                            ]
                        ),
                    },
                ],
            }
        )
    )
    return overlay


def test_the_rendered_example_applies_and_a_tree_commit_rolls_out(
    cluster: Any,
    namespace: str,
    operator: Any,
    robots: Callable[..., list[str]],
    fleet_label: str,
    tmp_path: Path,
) -> None:
    robots(3, {"fleet": fleet_label})
    robots(1, {"fleet": fleet_label, "coral.dev/canary": "true"}, start=9)
    overlay = _overlay(tmp_path, namespace, fleet_label)
    rendered = cluster.kubectl("kustomize", str(overlay)).stdout
    cluster.kubectl("apply", "--server-side", "-f", "-", input=rendered)
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    wait_settled(fleet, 4)
    first = set(fleet.revisions().values())
    tree_maps = {i["spec"]["tree"]["configMap"] for i in fleet.instances().values()}

    # The commit: a longer pause in the patrol; kustomize gives the tree a new ConfigMap name.
    tree = tmp_path / "base" / "tree.xml"
    tree.write_text(tree.read_text().replace('<Sleep msec="500"/>', '<Sleep msec="750"/>'))
    rendered = cluster.kubectl("kustomize", str(overlay)).stdout
    cluster.kubectl("apply", "--server-side", "-f", "-", input=rendered)
    wait_for(
        lambda: rollout_complete(fleet) and set(fleet.revisions().values()).isdisjoint(first),
        timeout=180,
        message=lambda: f"the new tree rolled out: {fleet.rollout()}",
    )
    wait_settled(fleet, 4)
    assert {i["spec"]["tree"]["configMap"] for i in fleet.instances().values()}.isdisjoint(tree_maps)
    rollout = fleet.rollout()
    assert len(rollout["history"]) == 2 and rollout["canary"]["promoted"]
