"""The Helm chart lints, renders the committed single-file manifest, and its RBAC is all the operator
needs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tarfile
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from coral_api import Coral, fleet_mission, is_current_and_true
from coral_testbed.cluster import binaries, processes
from fixtures.operator import opened_policy
from fixtures.processes import stop_process_group

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
    ],
)
def test_a_bad_value_is_refused_by_the_schema_naming_it(setting: str, named: str) -> None:
    for verb in (["lint", "--strict"], ["template", "c"]):
        result = subprocess.run(
            [_helm(), *verb, str(CHART), "--set", setting], capture_output=True, text=True
        )
        assert result.returncode != 0, f"helm {verb[0]} accepted {setting}"
        assert named in result.stdout + result.stderr


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
    release = f"c{uuid.uuid4().hex[:6]}"
    env = cluster.env()
    install = [
        _helm(),
        "install",
        release,
        str(CHART),
        "-n",
        namespace,
        "--wait=false",
        "--set",
        f"watchNamespaces={{{namespace}}}",
        "--set",
        f"policy.hostNetworkNamespaces={{{namespace}}}",
        # Keep the chart's own operator pod off the simulated robots; this test runs it as a process.
        "--set",
        "nodeSelector.coral-test=no-such-node",
    ]
    subprocess.run(install, env=env, check=True, capture_output=True, text=True)
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
    finally:
        if process is not None:
            stop_process_group(process, timeout=15)
        subprocess.run(
            [_helm(), "uninstall", release, "-n", namespace], env=env, check=True, capture_output=True
        )
    # The CRDs stay when the release goes (they live in the chart's crds/ folder).
    assert "coralsystems.coral.dev" in cluster.kubectl("get", "crd", "-o", "name").stdout
