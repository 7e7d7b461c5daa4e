"""The operator's metrics: what a scrape shows of the fleet and of the operator's own work, named
as Prometheus expects (checked by `promtool check metrics`), and with as many series for a
thousand robots as for three."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable

import pytest
from coral_operator.kube.workqueue import WorkQueue
from coral_operator.metrics.fleet import FleetCollector
from coral_operator.metrics.instruments import OperatorMetrics
from coral_operator.metrics.requests import request_info
from coral_testbed.waiting import wait_for
from metrics_fleet import NAMESPACE, Queue, fleet
from prometheus_client import CollectorRegistry, generate_latest
from prometheus_client.parser import text_string_to_metric_families


@pytest.mark.parametrize(
    ("method", "url", "expected"),
    [
        ("GET", "https://10.0.0.1:6443/api/v1/namespaces/robots/pods", ("list", "pods")),
        ("GET", "https://h/api/v1/namespaces/robots/pods/p1", ("get", "pods")),
        ("POST", "https://h/api/v1/namespaces/robots/pods", ("create", "pods")),
        (
            "DELETE",
            "https://h/api/v1/namespaces/robots/pods?labelSelector=a%3Db",
            ("deletecollection", "pods"),
        ),
        (
            "PATCH",
            "https://h/apis/coral.dev/v1alpha1/namespaces/robots/coralinstances/i1/status",
            ("patch", "coralinstances/status"),
        ),
        (
            "GET",
            "https://h/apis/coordination.k8s.io/v1/namespaces/kube-node-lease/leases/r1",
            ("get", "leases"),
        ),
        (
            "PUT",
            "https://h/apis/apps/v1/namespaces/robots/controllerrevisions/c",
            ("update", "controllerrevisions"),
        ),
        ("GET", "https://h/api/v1/namespaces/robots", ("get", "namespaces")),
        ("GET", "https://h/api/v1/nodes", ("list", "nodes")),
        ("GET", "https://h/version", ("get", "other")),
    ],
)
def test_a_request_is_counted_by_its_verb_and_resource_never_by_object(
    method: str, url: str, expected: tuple[str, str]
) -> None:
    assert request_info(method, url) == expected


def _scrape(registry: CollectorRegistry) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    samples = {}
    for family in text_string_to_metric_families(generate_latest(registry).decode()):
        for sample in family.samples:
            samples[(sample.name, tuple(sorted(sample.labels.items())))] = sample.value
    return samples


def _sample(name: str, **labels: str) -> tuple[str, tuple[tuple[str, str], ...]]:
    return (name, tuple(sorted(labels.items())))


def test_a_scrape_shows_robots_by_state_instances_by_condition_and_tree_and_rollout_progress() -> None:
    registry = CollectorRegistry()
    registry.register(FleetCollector(fleet(3), Queue(depth=4, wait_s=1.5)))
    samples = _scrape(registry)
    system = {"namespace": NAMESPACE, "system": "fleet"}
    assert samples[_sample("coral_robots", state="ready")] == 2
    assert samples[_sample("coral_robots", state="unreachable")] == 1
    assert samples[_sample("coral_robots", state="not_ready")] == 0
    assert samples[_sample("coral_instances", **system, condition="Ready", status="True")] == 2
    assert samples[_sample("coral_instances", **system, condition="RobotReachable", status="False")] == 1
    assert samples[_sample("coral_instance_trees", **system, state="RUNNING")] == 2
    assert samples[_sample("coral_instance_trees", **system, state="FAILURE")] == 1
    assert samples[_sample("coral_rollout_robots", **system, count="updated")] == 2
    assert samples[_sample("coral_rollout_complete", **system)] == 0
    # A system without instances keeps its series, at zero, so alerts see it rather than nothing.
    empty = {"namespace": NAMESPACE, "system": "empty"}
    assert samples[_sample("coral_instance_trees", **empty, state="RUNNING")] == 0
    assert samples[_sample("coral_operator_workqueue_depth")] == 4
    assert samples[_sample("coral_operator_workqueue_longest_wait_seconds")] == 1.5


def test_a_thousand_robots_make_as_many_series_as_three() -> None:
    def series(robots: int) -> set[tuple[str, tuple[tuple[str, str], ...]]]:
        registry = CollectorRegistry()
        registry.register(FleetCollector(fleet(robots), Queue(0, 0.0)))
        return set(_scrape(registry))

    assert series(1000) == series(3)


def test_passes_are_counted_by_kind_and_result_with_their_durations() -> None:
    registry = CollectorRegistry()
    metrics = OperatorMetrics(registry)

    def process(key: tuple[str, str]) -> None:
        if key[1] == "broken":
            raise RuntimeError("the API server refused")

    queue: WorkQueue[tuple[str, str]] = WorkQueue(
        process,
        workers=2,
        retry_base_s=60.0,
        on_pass=lambda key, *outcome: metrics.observe_pass(key[0], *outcome),
    )
    queue.add(("CoralSystem", "fleet"))
    queue.add(("CoralInstance", "a"))
    queue.add(("CoralInstance", "broken"))
    queue.start()
    try:
        count: Callable[[str, str], float] = lambda kind, result: _scrape(registry).get(  # noqa: E731
            _sample("coral_operator_reconciles_total", kind=kind, result=result), 0.0
        )
        wait_for(lambda: count("CoralInstance", "error") == 1, timeout=5, message="the failed pass counted")
        wait_for(lambda: count("CoralInstance", "success") == 1, timeout=5, message="the pass counted")
        assert count("CoralSystem", "success") == 1
        samples = _scrape(registry)
        assert samples[_sample("coral_operator_reconcile_duration_seconds_count", kind="CoralInstance")] == 2
        assert (
            samples[_sample("coral_operator_workqueue_queue_duration_seconds_count", kind="CoralSystem")] == 1
        )
        # The failed key is due again only after its backoff: it waits, it is not overdue.
        assert queue.longest_wait_s() == 0.0
    finally:
        queue.stop()


def test_the_exposition_follows_prometheus_naming_conventions() -> None:
    promtool = shutil.which("promtool")
    if promtool is None:
        pytest.skip("promtool comes with Debian's prometheus package (hack/setup-node-runtime.sh)")
    registry = CollectorRegistry()
    metrics = OperatorMetrics(registry)
    metrics.observe_pass("CoralSystem", False, 0.01, 0.2)
    metrics.observe_request(
        "PATCH", "https://h/apis/coral.dev/v1alpha1/namespaces/n/coralinstances/i/status", 200
    )
    registry.register(FleetCollector(fleet(3), Queue(0, 0.0)))
    checked = subprocess.run(
        [promtool, "check", "metrics"], input=generate_latest(registry), capture_output=True, check=False
    )
    assert checked.returncode == 0, checked.stdout.decode() + checked.stderr.decode()
    assert not checked.stdout.strip() and not checked.stderr.strip(), (
        checked.stdout.decode() + checked.stderr.decode()
    )
