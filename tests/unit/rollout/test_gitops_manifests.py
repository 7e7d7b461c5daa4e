"""The Argo CD Application and the Flux Kustomization of examples/gitops point at the kustomization
that the integration test renders and applies."""

from __future__ import annotations

from pathlib import Path

import yaml

GITOPS = Path(__file__).resolve().parents[3] / "examples" / "gitops"


def test_argo_cd_syncs_the_fleet_kustomization_with_pruning_and_self_heal() -> None:
    app = yaml.safe_load((GITOPS / "argocd" / "application.yaml").read_text())
    assert app["apiVersion"] == "argoproj.io/v1alpha1" and app["kind"] == "Application"
    source = app["spec"]["source"]
    assert (GITOPS.parents[1] / source["path"] / "kustomization.yaml").is_file()
    assert app["spec"]["destination"]["namespace"] == "fleet"
    assert app["spec"]["syncPolicy"]["automated"] == {"prune": True, "selfHeal": True}


def test_flux_applies_the_fleet_kustomization_from_its_git_repository_and_waits_for_the_system() -> None:
    repo = yaml.safe_load((GITOPS / "flux" / "gitrepository.yaml").read_text())
    kustomization = yaml.safe_load((GITOPS / "flux" / "fleet-kustomization.yaml").read_text())
    assert repo["kind"] == "GitRepository" and kustomization["kind"] == "Kustomization"
    assert kustomization["apiVersion"].startswith("kustomize.toolkit.fluxcd.io/")
    assert kustomization["spec"]["sourceRef"] == {"kind": "GitRepository", "name": repo["metadata"]["name"]}
    path = kustomization["spec"]["path"].removeprefix("./")
    assert (GITOPS.parents[1] / path / "kustomization.yaml").is_file()
    # Flux ignores `healthChecks` when `wait: true`; our kinds need `healthCheckExprs` (kstatus
    # alone calls a CoralSystem without conditions Current).
    assert kustomization["spec"]["wait"] is True and "healthChecks" not in kustomization["spec"]
    exprs = {e["kind"]: e for e in kustomization["spec"]["healthCheckExprs"]}
    assert set(exprs) == {"CoralSystem", "CoralInstance"}
    assert all(
        e["apiVersion"] == "coral.dev/v1alpha1" and e["current"] and e["failed"] for e in exprs.values()
    )


def test_the_kustomization_generates_the_tree_and_parameters_the_system_references() -> None:
    kustomization = yaml.safe_load((GITOPS / "fleet" / "kustomization.yaml").read_text())
    generated = {g["name"]: g["files"] for g in kustomization["configMapGenerator"]}
    system = yaml.safe_load((GITOPS / "fleet" / "coralsystem.yaml").read_text())
    tree_ref = system["spec"]["tree"]["configMapRef"]
    params_ref = system["spec"]["parameters"]["configMapRef"]
    assert generated[tree_ref["name"]] == [tree_ref["key"]]
    assert generated[params_ref["name"]] == [params_ref["key"]]
    for files in generated.values():
        assert all((GITOPS / "fleet" / f).is_file() for f in files)


def test_the_docs_show_the_flux_expressions_the_example_uses() -> None:
    docs = (GITOPS.parents[1] / "docs" / "verdicts.md").read_text()
    block = docs.split("```yaml", 1)[1].split("```", 1)[0]
    documented = yaml.safe_load("spec:\n" + block)["spec"]["healthCheckExprs"]
    example = yaml.safe_load((GITOPS / "flux" / "fleet-kustomization.yaml").read_text())["spec"]
    assert documented == example["healthCheckExprs"]


def test_the_argocd_cm_patch_carries_the_health_script_for_both_kinds() -> None:
    argocd = GITOPS.parents[1] / "charts" / "coral-operator" / "argocd"
    patch = yaml.safe_load((argocd / "argocd-cm.yaml").read_text())
    script = (argocd / "health.lua").read_text()
    assert (patch["kind"], patch["metadata"]["name"], patch["metadata"]["namespace"]) == (
        "ConfigMap",
        "argocd-cm",
        "argocd",
    )
    assert patch["data"] == {
        "resource.customizations.health.coral.dev_CoralSystem": script,
        "resource.customizations.health.coral.dev_CoralInstance": script,
    }
