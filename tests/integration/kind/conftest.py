"""One kind cluster for every test of this folder: three robot workers and the operator's node.

`kind_cluster` creates it once, the way `coral dev-cluster up` does but with the test heartbeats
(`components.TEST_HEARTBEATS`: a robot cut off turns Unknown in about 12 s, not kind's 50), and
deletes it after the folder's last test; then nothing of it may be left (no container, network or
registry; the project's dockerd, its mounts and cgroups too unless another kind cluster still runs
on it; the host's ip_forward and iptables as before). `kind_missions` is the operator installed
on it by its Helm chart, serving one namespace, with the mission images in the cluster's registry;
`kind_operator` is that for one test, its CoralSystems deleted after it. They skip, with the
reason, where kind cannot run. `short_bag` is the missions' short synthetic bag and
`slam_robot` the robot that has it where the SLAM example's bag player reads it.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from coral.lidar import generating
from coral_core.component_image import COMPONENT_UID
from coral_testbed import images
from coral_testbed.cluster import binaries, components, nodeimages, operatorchart
from coral_testbed.cluster.client import Cluster
from coral_testbed.images import registry
from coral_testbed.kind import clusters, engine, provisioning
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.missions import manifests, stack
from fixtures.cluster import create_test_namespace
from kubernetes import client as k8s
from missions.conftest import TEST_SCANS

from .fleet import MISSIONS_NAMESPACE, NAME, ROBOTS, KindCluster


def _host_network_state() -> tuple[str, str]:
    forwarding = Path("/proc/sys/net/ipv4/ip_forward").read_text().strip()
    rules = subprocess.run(["iptables-save"], capture_output=True, text=True).stdout
    # iptables-save stamps each dump with the time; only the rules matter.
    return forwarding, "\n".join(line for line in rules.splitlines() if not line.startswith("#"))


def _mounts_under(folder: Path) -> list[str]:
    return [line for line in Path("/proc/mounts").read_text().splitlines() if str(folder) in line]


def _assert_nothing_left(node_engine: engine.Engine, engine_stopped: bool) -> None:
    assert not registry.recorded_addresses(clusters.state_dir(NAME)), "the cluster's registry still runs"
    if engine_stopped:
        assert not node_engine.is_serving(), "the project's dockerd still runs"
        assert not _mounts_under(engine.engine_dir()), "mounts of the project's dockerd are left"
        assert not engine.leftover_cgroups(), "cgroups of the project's dockerd are left"
    else:
        assert not node_engine.containers(f"{clusters.KIND_CLUSTER_LABEL}={NAME}")
        networks = node_engine.docker("network", "ls", "--format", "{{.Name}}").stdout.split()
        assert clusters.network_name(NAME) not in networks


@pytest.fixture(scope="package")
def kind_cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[KindCluster]:
    """The cluster, with the python image in its registry and a site share on every robot (a host
    folder, as an NFS mount would be on a site); everything gone afterwards."""
    reason = provisioning.unsupported_reason()
    if reason:
        pytest.skip(reason)
    host_before = _host_network_state()
    ready = provisioning.ensure(print)
    share = tmp_path_factory.mktemp("site-share")
    # The components run as their own user and write the share, as on a site's NFS export.
    os.chown(share, COMPONENT_UID, COMPONENT_UID)
    try:
        running = clusters.create(
            NAME,
            ROBOTS,
            ready.engine,
            ready.node_image,
            print,
            extra_workers={stack.OPERATOR_NODE: {operatorchart.OPERATOR_NODE_LABEL: "true"}},
            robot_mounts={manifests.SITE_SHARE: str(share)},
            heartbeats=components.TEST_HEARTBEATS,
        )
        images.build(["python"], registry_address=running.registry_address)
        cluster = Cluster(running.kubeconfig, binaries.find_bin_dir(("kubectl", "helm")), is_local=False)
        try:
            yield KindCluster(running, cluster, share)
        finally:
            cluster.close()
    finally:
        clusters.delete(NAME, ready.engine, print)
        # Another kind cluster on the project's dockerd (another checkout's tests, the other lane's
        # demo) keeps it running; the last cluster's run stops it.
        stopped = clusters.stop_engine_unless_used(ready.engine)
    _assert_nothing_left(ready.engine, stopped)
    assert _host_network_state() == host_before, "the host's ip_forward or iptables changed"


@pytest.fixture(scope="package")
def kind_missions(
    kind_cluster: KindCluster, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[KindMissionStack]:
    """The operator from its chart on the operator's node, serving `MISSIONS_NAMESPACE`, with the
    mission images in the cluster's registry; uninstalled with its namespace afterwards."""
    with KindMissionStack(
        kind_cluster.running,
        kind_cluster.cluster,
        MISSIONS_NAMESPACE,
        list(ROBOTS),
        tmp_path_factory.mktemp("kind-missions"),
        print,
    ) as missions:
        yield missions


@pytest.fixture
def kind_operator(kind_missions: KindMissionStack) -> Iterator[KindMissionStack]:
    """`kind_missions` for one test: the CoralSystems it made are deleted afterwards, and their
    pods gone, so the robots are free for the next test (also when this one failed)."""
    yield kind_missions
    kind_missions.delete_systems()


@pytest.fixture(scope="package")
def robot_test_image(kind_cluster: KindCluster, tmp_path_factory: pytest.TempPathFactory) -> str:
    """The busybox test image of `coral_testbed.cluster.nodeimages` in every node's containerd, by
    `kind load image-archive` (no registry holds it); its name."""
    archive = nodeimages.local_archive(tmp_path_factory.mktemp("test-image"))
    clusters.load_image_archive(kind_cluster.running, archive)
    return nodeimages.TEST_IMAGE


@pytest.fixture
def kind_namespace(kind_cluster: KindCluster, request: pytest.FixtureRequest) -> Iterator[str]:
    """A fresh namespace named after the test, deleted with what it holds afterwards."""
    core = k8s.CoreV1Api(kind_cluster.cluster.api_client)
    name = create_test_namespace(core, request.node.name)
    yield name
    core.delete_namespace(name)


@pytest.fixture(scope="package")
def short_bag() -> Path:
    """The synthetic dataset (bag + ground truth) of TEST_SCANS scans, generated once and cached."""
    return generating.cached_dataset(generating.BagParams(scans=TEST_SCANS))


@pytest.fixture(scope="package")
def slam_robot(kind_missions: KindMissionStack, short_bag: Path) -> str:
    """The robot the SLAM example runs on, with the short bag where the example's bag player reads it."""
    robot = manifests.RELAY_ROBOTS[0]
    kind_missions.place_bag(robot, short_bag / "bag", manifests.SLAM_BAG)
    return robot
