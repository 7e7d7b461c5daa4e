"""On an API server that cannot stream a watch's initial objects (WatchList off, as in Kubernetes
1.33 and before), the operator says so, lists what is there in pages, and serves it: a system
made before it started and one made after both get their first status.

A control plane of its own, started with `--feature-gates=WatchList=false`: were the operator to
take that server for one that streams, kopf would wait for an end of the initial events that
never comes and no index would ever fill.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from coral_api import Coral, fleet_mission
from coral_testbed.cluster import components, controlplane
from coral_testbed.cluster.client import Cluster
from coral_testbed.waiting import wait_for
from fixtures.cluster import create_test_namespace
from fixtures.operator import OperatorProcess, apply_crds
from kubernetes import client as k8s

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


@pytest.fixture
def cluster_without_watchlist(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    state_dir = tmp_path_factory.mktemp("no-watchlist")
    state = controlplane.start(
        state_dir,
        die_with_parent=True,
        heartbeats=components.TEST_HEARTBEATS,
        extra_args={"kube-apiserver": ["--feature-gates=WatchList=false"]},
    )
    handle = Cluster(state.kubeconfig, bin_dir=state.layout.bin_dir, is_local=True, state_dir=state_dir)
    try:
        yield handle
    finally:
        handle.close()
        controlplane.stop(state_dir)


def test_the_operator_lists_in_pages_and_serves_where_the_server_cannot_stream(
    cluster_without_watchlist: Cluster, tmp_path: Path
) -> None:
    cluster = cluster_without_watchlist
    apply_crds(cluster)
    namespace = create_test_namespace(k8s.CoreV1Api(cluster.api_client), "no-watchlist")
    coral = Coral(cluster.api_client, namespace)
    coral.create_system(fleet_mission("before", "nowhere"))
    operator = OperatorProcess(cluster, namespace, tmp_path)
    operator.start()
    try:
        wait_for(
            lambda: coral.served("before"),
            timeout=90,
            message=lambda: (
                f"the system made before the operator started; its log:\n{operator.logs()[-3000:]}"
            ),
        )
        coral.create_system(fleet_mission("after", "nowhere"))
        wait_for(
            lambda: coral.served("after"),
            timeout=30,
            message=lambda: (
                f"the system made after the operator started; its log:\n{operator.logs()[-3000:]}"
            ),
        )
        assert "does not stream a watch's objects (WatchList off)" in operator.logs()
    finally:
        operator.stop()
