"""Acceptance 3 of issue 14: the Flux and Argo CD examples, rendered with kustomize, pass a strict
server-side dry run against the real CRDs of those projects (tests/data/gitops-crds, see its README).

Regression story: the Flux example set `healthChecks` beside `wait: true` (which the Flux CRD
documents as ignored), and nothing checked that either example was valid for the projects it
targets.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

pytestmark = [pytest.mark.cluster]

ROOT = Path(__file__).resolve().parents[3]
CRDS = ROOT / "tests" / "data" / "gitops-crds"
EXAMPLES = ROOT / "examples" / "gitops"
NAMESPACES = ("flux-system", "argocd")


@pytest.fixture(scope="module")
def gitops_crds(cluster: Any) -> Iterator[None]:
    """The Flux and Argo CD CRDs and namespaces, installed for this module and removed after it."""
    for crd in sorted(CRDS.glob("*.yaml")):
        cluster.kubectl("apply", "--server-side", "-f", str(crd), timeout=120)
    names = [yaml.safe_load(crd.read_text())["metadata"]["name"] for crd in sorted(CRDS.glob("*.yaml"))]
    for name in names:
        cluster.kubectl("wait", "--for=condition=Established", f"crd/{name}", "--timeout=60s", timeout=70)
    for namespace in NAMESPACES:
        cluster.kubectl("create", "namespace", namespace, check=False)
    yield
    for namespace in NAMESPACES:
        cluster.kubectl("delete", "namespace", namespace, "--wait=false", check=False)
    for name in names:
        cluster.kubectl("delete", "crd", name, "--wait=false", check=False)


def _dry_run(cluster: Any, manifests: str, check: bool = True) -> Any:
    return cluster.kubectl(
        "apply",
        "--server-side",
        "--dry-run=server",
        "--validate=strict",
        "-f",
        "-",
        input=manifests,
        check=check,
        timeout=60,
    )


@pytest.mark.parametrize("example", ["flux", "argocd"])
def test_the_example_passes_a_strict_server_side_dry_run(
    cluster: Any, gitops_crds: None, example: str
) -> None:
    rendered = cluster.kubectl("kustomize", str(EXAMPLES / example)).stdout
    kinds = {d["kind"] for d in yaml.safe_load_all(rendered) if d}
    assert kinds == ({"GitRepository", "Kustomization"} if example == "flux" else {"Application"})
    out = _dry_run(cluster, rendered).stdout
    assert "serverside-applied (server dry run)" in out, out


def test_the_argo_cd_health_check_patch_passes_a_strict_server_side_dry_run(
    cluster: Any, gitops_crds: None
) -> None:
    patch = (ROOT / "charts" / "coral-operator" / "argocd" / "argocd-cm.yaml").read_text()
    assert "serverside-applied (server dry run)" in _dry_run(cluster, patch).stdout


def test_a_misspelt_field_is_refused_by_the_real_schema(cluster: Any, gitops_crds: None) -> None:
    """The dry run is strict: it would have caught an example with a field Flux does not know."""
    rendered = cluster.kubectl("kustomize", str(EXAMPLES / "flux")).stdout
    broken = rendered.replace("healthCheckExprs:", "healthCheckExpressions:")
    result = _dry_run(cluster, broken, check=False)
    assert result.returncode != 0 and "healthCheckExpressions" in result.stderr
