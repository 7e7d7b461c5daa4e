"""Acceptance 1 of issue 14: reverting a CoralSystem to an earlier spec converges.

Regression story: going A -> B -> A made the older ControllerRevision the newest again; the
operator patched its number, the apiserver re-encoded the immutable `data` and answered 422 on
every pass, so `observedGeneration` never advanced, robots stayed on B, kstatus said InProgress
and Argo CD Progressing forever. Only the pure history planner was tested.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
import verdict_clients
from fleet import Fleet, instance_ready, mission, wait_settled
from kubernetes import client as k8s

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def _history(cluster: Any, namespace: str) -> dict[str, int]:
    """Revision hash -> ControllerRevision number, as stored."""
    items = (
        k8s.AppsV1Api(cluster.api_client)
        .list_namespaced_controller_revision(namespace, label_selector="coral.dev/system=patrol")
        .items
    )
    return {item.metadata.labels["coral.dev/revision"]: item.revision for item in items}


def _assert_converged_on(fleet: Fleet, cluster: Any, namespace: str, revision: str, robots: int) -> None:
    wait_settled(fleet, robots)
    system = fleet.system()
    assert system["status"]["observedGeneration"] == system["metadata"]["generation"]
    assert set(fleet.revisions().values()) == {revision}
    assert system["status"]["revision"] == revision
    assert all(instance_ready(item) for item in fleet.instances().values())
    verdicts = verdict_clients.judge_all([system, *fleet.instances().values()])
    assert {v["kstatus"]["status"] for v in verdicts} == {"Current"}, verdicts
    assert {v["argo"]["status"] for v in verdicts} == {"Healthy"}, verdicts
    history = _history(cluster, namespace)
    assert history[revision] == max(history.values()), history
    assert list(history.values()).count(history[revision]) == 1, history


@pytest.mark.parametrize("changes", [["2", "1"], ["2", "3", "1"]], ids=["A-B-A", "A-B-C-A"])
def test_reverting_to_an_earlier_spec_converges(
    changes: list[str],
    cluster: Any,
    namespace: str,
    operator: Any,
    robots: Callable[..., list[str]],
    fleet_label: str,
) -> None:
    names = robots(3, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(mission("patrol", fleet_label, {"maxUnavailable": 1}))
    wait_settled(fleet, 3)
    seen = {"1": fleet.revisions()[names[0]]}
    for marker in changes:
        fleet.change(marker)
        wait_settled(fleet, 3)
        revision = fleet.system()["status"]["revision"]
        if marker in seen:
            assert revision == seen[marker], "the same spec is the same revision"
        seen[marker] = revision
        _assert_converged_on(fleet, cluster, namespace, revision, 3)
    # The history keeps every revision it saw (fewer than its limit of ten).
    assert set(_history(cluster, namespace)) == set(seen.values())


def test_a_revert_during_a_running_rollout_converges(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    names = robots(3, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(mission("patrol", fleet_label, {"maxUnavailable": 1, "interruptRunningTrees": False}))
    wait_settled(fleet, 3)
    first = fleet.revisions()[names[0]]
    # A mission RUNNING on the last robot holds it, so the rollout to B cannot finish.
    fleet.set_tree(names[2], "RUNNING")
    fleet.change("2")
    verdict_clients.wait_for_rollout(
        fleet,
        lambda revisions, rollout: (
            sum(r != first for r in revisions.values()) >= 1 and not rollout.get("complete")
        ),
        "some robots on B while the rollout is still running",
    )
    fleet.change("1")
    _assert_converged_on(fleet, cluster, namespace, first, 3)
