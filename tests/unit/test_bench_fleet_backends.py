"""The fleet benchmark's choice of cluster: the kind cluster's name from the command line, and the
control-plane processes whose CPU it counts, found among a kind node's processes."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture(scope="module")
def bench_fleet() -> Iterator[ModuleType]:
    # The benchmark imports its `fleet` package and `plots` from its own folder, as `python FILE` does.
    # A test folder elsewhere in the suite has a `fleet.py` of its own on the path; whichever came
    # first would shadow the other, so the benchmark's names are imported afresh and put back after.
    names = ("bench_fleet", "fleet", "plots")
    saved = {name: module for name, module in sys.modules.items() if name.split(".")[0] in names}
    for name in saved:
        del sys.modules[name]
    sys.path.insert(0, str(BENCHMARKS))
    try:
        yield importlib.import_module("bench_fleet")
    finally:
        sys.path.remove(str(BENCHMARKS))
        for name in [name for name in sys.modules if name.split(".")[0] in names]:
            del sys.modules[name]
        sys.modules.update(saved)


def test_a_kind_run_uses_the_cluster_name_it_is_given(bench_fleet: ModuleType) -> None:
    _, options = bench_fleet.parse_arguments(["100", "--cluster", "kind", "--kind-name", "wt-a-fleet"])
    assert (options.backend, options.kind_name) == ("kind", "wt-a-fleet")


def test_without_a_name_a_kind_run_uses_the_benchmarks_own(bench_fleet: ModuleType) -> None:
    args, options = bench_fleet.parse_arguments(["--cluster", "kind"])
    assert options.kind_name == "fleet-bench" and args.sizes == []


def test_kind_is_the_default_and_the_local_control_plane_is_asked_for_by_name(
    bench_fleet: ModuleType,
) -> None:
    _, options = bench_fleet.parse_arguments(["100"])
    assert options.backend == "kind"
    _, options = bench_fleet.parse_arguments(["100", "--cluster", "local"])
    assert options.backend == "local"


# `docker top NODE -eo pid,args` of a kind control-plane node, as dockerd 20.10 prints it.
_TOP = """PID                 COMMAND
9610                /sbin/init
12134               /pause
12382               kube-apiserver --advertise-address=10.89.0.2 --secure-port=6443
12200               etcd --advertise-client-urls=https://10.89.0.2:2379 --data-dir=/var/lib/etcd
12257               kube-scheduler --kubeconfig=/etc/kubernetes/scheduler.conf
12415               kube-controller-manager --allocate-node-cidrs=true
14268               /usr/local/bin/kube-proxy --config=/var/lib/kube-proxy/config.conf
14449               python /usr/local/bin/coral-kind-net
15001               /usr/bin/kubelet --config=/var/lib/kubelet/config.yaml
"""


def test_the_control_plane_is_found_among_a_kind_nodes_processes(bench_fleet: ModuleType) -> None:
    assert bench_fleet.backends.control_plane_pids(_TOP) == {
        "kube-apiserver": 12382,
        "etcd": 12200,
        "kube-scheduler": 12257,
        "kube-controller-manager": 12415,
    }
