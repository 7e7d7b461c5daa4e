"""The executor's ServiceAccount may patch its own instance's status and nothing else."""

from __future__ import annotations

import pytest
from coral.executor import kubernetes_sink as sink
from coral_api import GROUP, VERSION, denied, executor_client, executor_pod
from kubernetes import client as k8s
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_the_executor_account_writes_its_tree_status_and_nothing_else(scenario: Scenario) -> None:
    cluster, namespace, coral, wait = scenario.cluster, scenario.namespace, scenario.coral, scenario.wait
    mine, other = scenario.robots(2)
    scenario.deploy()
    instance = f"fleet-{mine}"
    executor = executor_pod(cluster, namespace, instance)
    as_executor = executor_client(cluster, namespace, instance)

    status_sink = sink.KubernetesStatusSink(
        sink.build_patcher(as_executor, namespace, instance), background=False
    )
    status_sink.emit(
        {
            "event": "status",
            "root_status": "RUNNING",
            "tick_count": 42,
            "active_path": "Patrol/patrol/RetryUntilSuccessful/EstimatePose",
            "last_failure": None,
        }
    )
    status_sink.close()
    assert status_sink.patches == 1

    tree = coral.instances()[instance]["status"]["tree"]
    assert (tree["rootStatus"], tree["tickCount"]) == ("RUNNING", 42)
    assert tree["activePath"].endswith("EstimatePose")
    wait(
        lambda: coral.system("fleet")["status"]["trees"]["running"] == 1,
        "the system summary to count the tree",
    )
    columns = cluster.kubectl("get", "coralinstance", instance, "-n", namespace).stdout
    assert "RUNNING" in columns

    custom = k8s.CustomObjectsApi(as_executor)
    core = k8s.CoreV1Api(as_executor)
    merge = "application/merge-patch+json"
    body = {"status": {"tree": {"rootStatus": "FAILURE"}}}
    assert denied(
        lambda: custom.patch_namespaced_custom_object_status(
            GROUP, VERSION, namespace, "coralinstances", f"fleet-{other}", body, _content_type=merge
        )
    ), "patching another robot's instance must be denied"
    assert denied(
        lambda: custom.patch_namespaced_custom_object_status(
            GROUP, VERSION, namespace, "coralsystems", "fleet", {"status": {}}, _content_type=merge
        )
    ), "patching the CoralSystem's status must be denied"
    assert denied(
        lambda: custom.patch_namespaced_custom_object(
            GROUP,
            VERSION,
            namespace,
            "coralinstances",
            instance,
            {"spec": {"robot": "x"}},
            _content_type=merge,
        )
    ), "patching its own instance's spec must be denied"
    assert denied(
        lambda: core.patch_namespaced_pod(
            executor.metadata.name, namespace, {"metadata": {"labels": {"x": "y"}}}, _content_type=merge
        )
    ), "patching a pod must be denied"
    assert coral.instances()[f"fleet-{other}"]["status"].get("tree") is None
