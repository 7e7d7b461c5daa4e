"""`coral validate` for Kubernetes manifests: the CoralSystems of a mission file or a rendered kustomization.

The same checks as for a compose project (`coral.local.checking`), applied to what a CoralSystem
carries: its tree (inline, or from a ConfigMap in the same input, as `kubectl kustomize` renders
a `configMapGenerator`), its ROS parameters and its components, looked up by image. Problems name
the input, the document's system and the field. Called by `coral.local.cli.validate_command`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import yaml
from coral_core import parsing

from coral.local import checking

_ROLES = ("drivers", "skillsets")
SOURCE_LABEL = "coral.dev/source"
"""The label (value "true") by which a ConfigMap's owners let CoralSystems name it in configMapRef."""


@dataclass
class _Inputs:
    systems: list[dict[str, Any]] = field(default_factory=list)
    config_maps: dict[tuple[str, str], dict[str, str]] = field(default_factory=dict)
    config_map_labels: dict[tuple[str, str], dict[str, str]] = field(default_factory=dict)


def looks_like_manifests(text: str) -> bool:
    """Whether a YAML file holds Kubernetes objects (rather than a compose project)."""
    try:
        documents = [d for d in parsing.load_all_yaml(text) if isinstance(d, dict)]
    except yaml.YAMLError:
        return False
    return any("apiVersion" in d and "kind" in d for d in documents)


def _collect(text: str, source: str, problems: list[str]) -> _Inputs:
    inputs = _Inputs()
    try:
        documents = parsing.load_all_yaml(text)
    except yaml.YAMLError as err:
        problems.append(f"{source}: not YAML: {err}")
        return inputs
    for document in documents:
        if not isinstance(document, dict):
            continue
        metadata = document.get("metadata") or {}
        key = (metadata.get("namespace") or "", metadata.get("name") or "")
        if document.get("kind") == "CoralSystem":
            inputs.systems.append(document)
        elif document.get("kind") == "ConfigMap":
            inputs.config_maps[key] = dict(document.get("data") or {})
            inputs.config_map_labels[key] = dict(metadata.get("labels") or {})
    return inputs


def _file_text(
    system: dict[str, Any], part: str, inputs: _Inputs, where: str, problems: list[str]
) -> str | None:
    spec = (system.get("spec") or {}).get(part) or {}
    if "inline" in spec:
        return str(spec["inline"])
    reference = spec.get("configMapRef")
    if not reference:
        return None
    namespace = (system.get("metadata") or {}).get("namespace") or ""
    data = inputs.config_maps.get((namespace, reference.get("name", "")))
    if data is None:
        problems.append(
            f"{where}: spec.{part}.configMapRef: ConfigMap {reference.get('name')} is not in the input"
        )
        return None
    if inputs.config_map_labels.get((namespace, reference.get("name", "")), {}).get(SOURCE_LABEL) != "true":
        # The operator reads only ConfigMaps their owners marked for Coral (docs/architecture.md).
        problems.append(
            f"{where}: spec.{part}.configMapRef: ConfigMap {reference.get('name')} lacks the label "
            f'{SOURCE_LABEL}: "true"; the operator would refuse it'
        )
        return None
    if reference.get("key") not in data:
        problems.append(
            f"{where}: spec.{part}.configMapRef: ConfigMap {reference.get('name')} "
            f"has no key {reference.get('key')}"
        )
        return None
    return data[reference["key"]]


def _check_system(system: dict[str, Any], inputs: _Inputs, source: str) -> list[str]:
    from coral_core import bt

    from coral.sdk import params

    name = (system.get("metadata") or {}).get("name", "?")
    where = f"{source}: coralsystem/{name}"
    problems: list[str] = []
    spec = system.get("spec") or {}
    manifests: dict[str, object] = {}
    for role in _ROLES:
        for index, component in enumerate(spec.get(role) or []):
            label = f"{where}: spec.{role}[{index}] ({component.get('name')})"
            if not component.get("image"):
                continue
            verification = checking.verify_component(str(component["image"]))
            problems += [f"{label}: {problem}" for problem in verification.problems]
            if verification.manifest is not None:
                manifests[str(component.get("name"))] = verification.manifest
    parameters = _file_text(system, "parameters", inputs, where, problems)
    if parameters is not None:
        try:
            params.validate_text(parameters, f"{where}: spec.parameters")
        except params.ParamsError as err:
            problems.append(str(err))
    tree = _file_text(system, "tree", inputs, where, problems)
    if tree is not None:
        registry = checking.registry_for(manifests)
        main_tree = (spec.get("tree") or {}).get("mainTreeId")
        try:
            document = bt.load_tree_text(tree, registry, filename=f"{where}: spec.tree", main_tree=main_tree)
            problems += [str(error) for error in bt.validate_document(document, registry)]
        except bt.BTError as err:
            problems.append(str(err))
    return problems


def validate_manifests(text: str, source: str) -> checking.Report:
    """Every problem of every CoralSystem in `text` (YAML documents), named by `source` and field."""
    problems: list[str] = []
    inputs = _collect(text, source, problems)
    if not inputs.systems and not problems:
        problems.append(f"{source}: no CoralSystem in the input")
    for system in inputs.systems:
        problems += _check_system(system, inputs, source)
    return checking.Report(problems=problems)
