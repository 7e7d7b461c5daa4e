"""The Helm chart lints, renders the committed single-file manifest, and its RBAC is all the operator
needs."""

from __future__ import annotations

import contextlib
import json
import re
import subprocess
import sys
import tarfile
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from coral_api import Coral, fleet_mission, is_current_and_true
from coral_operator.planning import naming
from coral_testbed.cluster import audit, binaries, processes
from fixtures.operator import opened_policy
from fixtures.processes import stop_process_group
from kubernetes import client as k8s

ROOT = Path(__file__).resolve().parents[3]
CHART = ROOT / "charts" / "coral-operator"


def _helm() -> str:
    return str(binaries.find_bin_dir(("helm",)) / "helm")


def test_helm_lint_passes_for_cluster_wide_and_namespaced_installs() -> None:
    for extra in (
        [],
        ["--set", "watchNamespaces={robots,lab}", "--set", "policy.privilegedNamespaces={robots}"],
    ):
        result = subprocess.run(
            [_helm(), "lint", "--strict", str(CHART), *extra], capture_output=True, text=True
        )
        assert result.returncode == 0, result.stdout + result.stderr


def test_the_single_file_manifest_is_the_rendered_chart() -> None:
    result = subprocess.run(
        [sys.executable, str(ROOT / "hack" / "render-manifest.py"), "--check", "--helm", _helm()],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    documents = [d for d in yaml.safe_load_all((ROOT / "deploy" / "coral-operator.yaml").read_text()) if d]
    kinds = [d["kind"] for d in documents]
    assert kinds.count("CustomResourceDefinition") == 2
    deployment = next(d for d in documents if d["kind"] == "Deployment")
    assert deployment["spec"]["replicas"] == 1
    assert deployment["spec"]["strategy"] == {"type": "Recreate"}


@pytest.mark.parametrize(
    ("setting", "named"),
    [
        ("livenessPort=abc", "livenessPort"),
        ("livenessPort=70000", "livenessPort"),
        ("image.pullPolicy=Sometimes", "pullPolicy"),
        ("watchNamespaces={Not_A_Namespace}", "watchNamespaces"),
        ("livenesPort=8080", "livenesPort"),
        ("metrics.port=0", "port"),
        ("metrics.serviceMonitor.interval=often", "interval"),
    ],
)
def test_a_bad_value_is_refused_by_the_schema_naming_it(setting: str, named: str) -> None:
    for verb in (["lint", "--strict"], ["template", "c"]):
        result = subprocess.run(
            [_helm(), *verb, str(CHART), "--set", setting], capture_output=True, text=True
        )
        assert result.returncode != 0, f"helm {verb[0]} accepted {setting}"
        assert named in result.stdout + result.stderr


def _rendered(*settings: str) -> list[dict[str, Any]]:
    arguments = [arg for setting in settings for arg in ("--set", setting)]
    result = subprocess.run(
        [_helm(), "template", "c", str(CHART), *arguments], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    return [d for d in yaml.safe_load_all(result.stdout) if d]


MONITORING_KINDS = {"ServiceMonitor", "PodMonitor", "PrometheusRule"}


def test_the_operator_serves_metrics_behind_a_service_and_nothing_needs_prometheus_operator_by_default() -> (
    None
):
    documents = _rendered()
    assert not MONITORING_KINDS & {d["kind"] for d in documents}
    assert not [d for d in documents if d["kind"] == "ConfigMap"]
    service = next(d for d in documents if d["kind"] == "Service" and d["metadata"]["name"] == "c-metrics")
    container = next(d for d in documents if d["kind"] == "Deployment")["spec"]["template"]["spec"][
        "containers"
    ][0]
    assert "--metrics=0.0.0.0:8081" in container["args"]
    assert {"name": "metrics", "containerPort": 8081} in container["ports"]
    assert service["spec"]["ports"] == [{"name": "metrics", "port": 8081, "targetPort": "metrics"}]
    off = _rendered("metrics.enabled=false")
    assert not [d for d in off if d["kind"] == "Service"]
    assert not any(
        a.startswith("--metrics")
        for d in off
        if d["kind"] == "Deployment"
        for a in d["spec"]["template"]["spec"]["containers"][0]["args"]
    )


def test_the_monitors_rules_and_dashboard_ship_the_files_that_are_tested() -> None:
    documents = _rendered(
        "metrics.serviceMonitor.enabled=true",
        "metrics.serviceMonitor.labels.release=prometheus",
        "metrics.podMonitor.enabled=true",
        "metrics.prometheusRule.enabled=true",
        "metrics.grafanaDashboard.enabled=true",
    )
    by_kind = {d["kind"]: d for d in documents if d["kind"] in MONITORING_KINDS | {"ConfigMap"}}
    rules = yaml.safe_load((CHART / "monitoring" / "rules.yaml").read_text())
    assert by_kind["PrometheusRule"]["spec"]["groups"] == rules["groups"]
    dashboard = json.loads(by_kind["ConfigMap"]["data"]["coral-fleet.json"])
    assert dashboard == json.loads((CHART / "monitoring" / "coral-fleet-dashboard.json").read_text())
    assert by_kind["ConfigMap"]["metadata"]["labels"]["grafana_dashboard"] == "1"
    service = next(d for d in documents if d["kind"] == "Service" and d["metadata"]["name"] == "c-metrics")
    monitor = by_kind["ServiceMonitor"]
    assert monitor["metadata"]["labels"]["release"] == "prometheus"
    assert monitor["spec"]["selector"]["matchLabels"].items() <= service["metadata"]["labels"].items()
    assert monitor["spec"]["endpoints"][0]["port"] == "metrics"
    assert by_kind["PodMonitor"]["spec"]["podMetricsEndpoints"][0]["port"] == "metrics"


def test_the_schema_covers_every_value_of_the_chart() -> None:
    schema = json.loads((CHART / "values.schema.json").read_text())
    values = yaml.safe_load((CHART / "values.yaml").read_text())

    def covered(value: Any, node: dict[str, Any], path: str) -> None:
        if isinstance(value, dict) and node.get("properties"):
            for key, item in value.items():
                assert key in node["properties"], f"{path}{key} is not in values.schema.json"
                covered(item, node["properties"][key], f"{path}{key}.")

    covered(values, schema, "")
    assert schema["additionalProperties"] is False


def test_the_chart_package_ships_the_argo_cd_health_check(tmp_path: Path) -> None:
    subprocess.run([_helm(), "package", str(CHART), "-d", str(tmp_path)], check=True, capture_output=True)
    (package,) = tmp_path.glob("coral-operator-*.tgz")
    with tarfile.open(package) as archive:
        names = set(archive.getnames())
    assert {
        "coral-operator/argocd/health.lua",
        "coral-operator/argocd/argocd-cm.yaml",
        "coral-operator/argocd/README.md",
        "coral-operator/values.schema.json",
    } <= names
    assert not any("/argocd/testdata/" in name for name in names)


def test_the_kubectl_manifest_does_not_claim_helm_manages_it() -> None:
    documents = [d for d in yaml.safe_load_all((ROOT / "deploy" / "coral-operator.yaml").read_text()) if d]
    labelled = [d for d in documents if (d["metadata"].get("labels") or {}).get("app.kubernetes.io/name")]
    assert labelled
    assert not any("app.kubernetes.io/managed-by" in d["metadata"]["labels"] for d in labelled)


def test_a_namespaced_install_grants_no_cluster_wide_writes() -> None:
    rendered = subprocess.run(
        [_helm(), "template", "c", str(CHART), "--set", "watchNamespaces={robots}"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    documents = [d for d in yaml.safe_load_all(rendered) if d]
    cluster_roles = [d for d in documents if d["kind"] == "ClusterRole"]
    assert len(cluster_roles) == 1
    verbs = {v for rule in cluster_roles[0]["rules"] for v in rule["verbs"]}
    assert verbs == {"get", "list", "watch"}
    roles = [d for d in documents if d["kind"] == "Role" and d["metadata"]["namespace"] != "kube-node-lease"]
    assert [r["metadata"]["namespace"] for r in roles] == ["robots"]
    # The robots' Node Leases are only read (when a robot is unreachable, for "last seen").
    leases = [d for d in documents if d["kind"] == "Role" and d["metadata"]["namespace"] == "kube-node-lease"]
    assert [rule for r in leases for rule in r["rules"]] == [
        {"apiGroups": ["coordination.k8s.io"], "resources": ["leases"], "verbs": ["get"]}
    ]
    assert all(
        "*" not in rule["verbs"] and "*" not in rule["resources"] for r in roles for rule in r["rules"]
    )


def _token_kubeconfig(cluster: Any, namespace: str, account: str, path: Path) -> Path:
    token = cluster.kubectl("create", "token", account, "-n", namespace, "--duration=30m").stdout.strip()
    admin = yaml.safe_load(Path(cluster.kubeconfig).read_text())
    context = next(c for c in admin["contexts"] if c["name"] == admin["current-context"])["context"]
    entry = next(c for c in admin["clusters"] if c["name"] == context["cluster"])
    path.write_text(
        yaml.safe_dump(
            {
                "apiVersion": "v1",
                "kind": "Config",
                "clusters": [entry],
                "users": [{"name": account, "user": {"token": token}}],
                "contexts": [{"name": "operator", "context": {"cluster": entry["name"], "user": account}}],
                "current-context": "operator",
            }
        )
    )
    return path


def _values_for(namespace: str) -> list[str]:
    """The chart's values for an operator of `namespace` that runs as a process, not as the chart's pod."""
    return [
        "--set",
        f"watchNamespaces={{{namespace}}}",
        "--set",
        f"policy.hostNetworkNamespaces={{{namespace}}}",
        # Keep the chart's own operator pod off the simulated robots; this test runs it as a process.
        "--set",
        "nodeSelector.coral-test=no-such-node",
    ]


@contextlib.contextmanager
def _operator_as_the_release(cluster: Any, namespace: str, tmp_path: Path) -> Iterator[str]:
    """Installs the chart in `namespace` and runs the operator as a process with nothing but the
    release's ServiceAccount token, its output in `tmp_path`/operator.log; yields the release name.
    Stops the operator and uninstalls the release afterwards."""
    release = f"c{uuid.uuid4().hex[:6]}"
    env = cluster.env()
    subprocess.run(
        [_helm(), "install", release, str(CHART), "-n", namespace, "--wait=false", *_values_for(namespace)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    process = None
    try:
        kubeconfig = _token_kubeconfig(cluster, namespace, release, tmp_path / "operator.kubeconfig")
        log = (tmp_path / "operator.log").open("w")
        process = subprocess.Popen(
            [sys.executable, "-m", "coral_operator", "-n", namespace],
            env={**env, **opened_policy(namespace), "KUBECONFIG": str(kubeconfig), "PYTHONUNBUFFERED": "1"},
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            preexec_fn=processes.die_with_parent,
        )
        yield release
    finally:
        if process is not None:
            stop_process_group(process, timeout=15)
        subprocess.run(
            [_helm(), "uninstall", release, "-n", namespace], env=env, check=True, capture_output=True
        )


@pytest.mark.cluster
@pytest.mark.slow
def test_the_operator_runs_with_nothing_but_the_charts_rbac(
    cluster: Any,
    namespace: str,
    coral_crds: None,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Any,
    tmp_path: Path,
) -> None:
    with _operator_as_the_release(cluster, namespace, tmp_path):
        robots(2, {"fleet": fleet_label})
        coral = Coral(cluster.api_client, namespace)
        coral.create_system(fleet_mission("fleet", fleet_label))
        wait(
            lambda: is_current_and_true(coral.system("fleet"), "Ready"),
            "the system to become Ready",
            timeout=120,
        )
        text = (tmp_path / "operator.log").read_text()
        # A status 403, not the milliseconds of a log line's timestamp (",403").
        refused = re.search(r"(?<![,\d])403(?!\d)", text) or "Forbidden" in text
        assert not refused, text[-3000:]
    # The CRDs stay when the release goes (they live in the chart's crds/ folder).
    assert "coralsystems.coral.dev" in cluster.kubectl("get", "crd", "-o", "name").stdout


Permission = tuple[str, str, str]
"""(API group, resource[/subresource], verb)."""

NOT_EXERCISED: dict[Permission, str] = {
    ("coordination.k8s.io", "leases", "get"): "read only while a robot is unreachable (its last-seen time)",
    ("coral.dev", "coralsystems", "get"): "a system whose files pass 16 KiB is read again by each pass",
    ("coral.dev", "coralinstances", "get"): "an instance name that answers 409 is read to tell whose it is",
    ("", "configmaps", "delete"): "a revision's files go when it leaves the history (after 10 changes)",
    ("apps", "controllerrevisions", "delete"): "a revision leaves the history after 10 changes",
    # Where the API server streams a watch's objects (WatchList), kopf starts its watches without
    # listing: these are asked only by a server without it (test_operator_without_watchlist.py).
    **{
        (group, resource, "list"): "a watch's first listing, where the API server cannot stream it"
        for group, resource in [
            ("", "configmaps"),
            ("", "nodes"),
            ("", "pods"),
            ("apiextensions.k8s.io", "customresourcedefinitions"),
        ]
    },
}
"""Grants of the chart that the scenario below does not reach, each with the only case that needs it."""


def _granted(rendered: str, account: str) -> set[Permission]:
    """Every (group, resource, verb) the rendered chart grants the ServiceAccount `account`."""
    documents = [d for d in yaml.safe_load_all(rendered) if d]
    roles = {(d["kind"], d["metadata"]["name"]): d for d in documents if d["kind"] in ("Role", "ClusterRole")}
    granted = set()
    for binding in (d for d in documents if d["kind"] in ("RoleBinding", "ClusterRoleBinding")):
        if not any(s["kind"] == "ServiceAccount" and s["name"] == account for s in binding["subjects"]):
            continue
        role = roles[(binding["roleRef"]["kind"], binding["roleRef"]["name"])]
        for rule in role["rules"]:
            granted |= {
                (group, resource, verb)
                for group in rule["apiGroups"]
                for resource in rule["resources"]
                for verb in rule["verbs"]
            }
    return granted


@pytest.mark.cluster
@pytest.mark.slow
def test_every_request_of_the_operator_is_granted_by_the_chart_and_every_grant_is_used(
    cluster: Any,
    namespace: str,
    coral_crds: None,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Any,
    tmp_path: Path,
) -> None:
    """Issue 47, item 8: the shipped ClusterRole lacked `get` on ServiceAccounts, so a second robot
    joining a system left it Stalled (ApplyRefused), which no test saw: they all ran the operator as
    an administrator, or only created a system. Here the operator runs with the chart's
    ServiceAccount through a system's whole life (create, grow from one robot to three, a change
    and its undoing, a robot leaving, objects that lost their owner adopted again as a robot joins,
    a delete), and the API server's audit log says what it really asked: nothing refused, nothing
    asked that the chart does not grant, and nothing granted that it never asks but
    `NOT_EXERCISED` (so removing a verb from the chart, or granting one too many, fails here)."""
    if cluster.state_dir is None:
        pytest.skip("needs the local control plane's audit log")
    with _operator_as_the_release(cluster, namespace, tmp_path) as release:
        coral = Coral(cluster.api_client, namespace)

        def ready_on(count: int) -> bool:
            system = coral.system("fleet")
            current = [i for i in coral.instances().values() if is_current_and_true(i, "Ready")]
            return is_current_and_true(system, "Ready") and len(current) == count

        def operator_log() -> str:
            return (tmp_path / "operator.log").read_text()[-3000:]

        first = robots(1, {"fleet": fleet_label})
        coral.create_system(fleet_mission("fleet", fleet_label))
        wait(lambda: ready_on(1), lambda: f"one Ready robot; operator log:\n{operator_log()}", timeout=120)
        # The second and third robots join a system that exists: its account is applied again.
        robots(2, {"fleet": fleet_label}, start=2)
        wait(lambda: ready_on(3), lambda: f"three Ready robots; operator log:\n{operator_log()}", timeout=120)
        # A change of the executors only (their pods replaced one by one, the others relabelled), one
        # every pod carries (all of an instance's pods replaced in one request), then that one
        # undone: the second revision becomes the newest again (renumbered in place).
        changes = [{"tree": {"tickRateHz": 5.0}}, {"ros": {"domainId": 7}}, {"ros": {"domainId": 0}}]
        for generation, change in enumerate(changes, start=2):
            coral.patch_system("fleet", {"spec": change})
            wait(
                lambda generation=generation: ready_on(3)
                and len({i["spec"]["revision"] for i in coral.instances().values()}) == 1
                and (coral.system("fleet") or {}).get("status", {}).get("observedGeneration") == generation,
                lambda: f"the change rolled out; operator log:\n{operator_log()}",
                timeout=180,
            )
        cluster.remove_robots(first)
        wait(lambda: ready_on(2) and len(coral.instances()) == 2, "the robot that left to lose its instance")
        # Objects that lost their owner reference (as an orphaning delete of the system leaves them)
        # are adopted again by the system of their name (kube.applying.create_owned) when a robot
        # joins, which applies them anew.
        core, rbac = k8s.CoreV1Api(cluster.api_client), k8s.RbacAuthorizationV1Api(cluster.api_client)
        account = naming.executor_account_name("fleet")
        strip = {"metadata": {"ownerReferences": None}}
        core.patch_namespaced_service_account(account, namespace, strip)
        rbac.patch_namespaced_role(account, namespace, strip)
        rbac.patch_namespaced_role_binding(account, namespace, strip)
        for name in coral.config_maps():
            core.patch_namespaced_config_map(name, namespace, strip)
        robots(1, {"fleet": fleet_label}, start=4)

        def adopted() -> bool:
            owners = [
                core.read_namespaced_service_account(account, namespace).metadata.owner_references,
                rbac.read_namespaced_role(account, namespace).metadata.owner_references,
                rbac.read_namespaced_role_binding(account, namespace).metadata.owner_references,
            ]
            return all(owners) and ready_on(3)

        wait(adopted, lambda: f"the system to adopt its objects again; log:\n{operator_log()}", timeout=120)
        coral.delete_system("fleet")
        wait(lambda: not coral.instances(), "the instances to go with their system", timeout=120)
    rendered = subprocess.run(
        [_helm(), "template", release, str(CHART), "-n", namespace, *_values_for(namespace)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    layout_log = Path(cluster.state_dir) / "logs" / "audit.log"
    requests = audit.requests_of(layout_log, f"system:serviceaccount:{namespace}:{release}")
    assert requests, f"no request of the operator in {layout_log}"
    refused = sorted({(r.permission, r.namespace) for r in requests if r.code == 403})
    assert not refused, f"the API server refused the operator: {refused}"
    used = {r.permission for r in requests}
    granted = _granted(rendered, release)
    assert used - granted == set(), "asked without a grant (answered otherwise than 403?)"
    unused = granted - used
    assert unused == set(NOT_EXERCISED), (
        f"granted but never asked: {sorted(unused - set(NOT_EXERCISED))}; "
        f"expected to be asked: {sorted(set(NOT_EXERCISED) - unused)}"
    )
