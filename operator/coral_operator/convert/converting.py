"""Builds the CoralSystem manifest from a folder of Coral files (compose, tree XML, parameters YAML).

Called by `coral convert` (`convert.cli`). The tree and parameters are inlined, so the output is
one self-contained file for `kubectl apply`; both are validated first, like the operator does.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from coral_core import bt, names, parsing
from coral_core.names import API_VERSION
from pydantic import ValidationError

from coral_operator.api.system import CoralSystemSpec
from coral_operator.convert.compose import ConvertError, component_name, kubernetes_fields
from coral_operator.planning import naming, system_pass, validation

PARAMS_IN_CONTAINER = "/etc/coral/params.yaml"
GROUPS = {"driver": "drivers", "skillset": "skillsets", "executor": "executors"}
# Environment variables that are ROS settings of the whole system rather than of one component.
_ROS_ENV = {"ROS_DOMAIN_ID", "RMW_IMPLEMENTATION", "ROS_LOCALHOST_ONLY", "ROS_AUTOMATIC_DISCOVERY_RANGE"}


def _ros(environments: list[dict[str, str]]) -> dict[str, Any]:
    ros: dict[str, Any] = {}
    for env in environments:
        if "ROS_DOMAIN_ID" in env:
            ros["domainId"] = int(env["ROS_DOMAIN_ID"])
        if "RMW_IMPLEMENTATION" in env:
            ros["rmwImplementation"] = env["RMW_IMPLEMENTATION"]
        if env.get("ROS_LOCALHOST_ONLY") == "1" or env.get("ROS_AUTOMATIC_DISCOVERY_RANGE") == "LOCALHOST":
            ros["localhostOnly"] = True
    return ros


def convert(
    *,
    folder: Path,
    selector: dict[str, str],
    name: str | None = None,
    namespace: str | None = None,
    tree: Path | None = None,
    params: Path | None = None,
    environ: Mapping[str, str] | None = None,
) -> tuple[dict[str, Any], list[str]]:
    """The CoralSystem manifest and the conversion warnings; raises ConvertError naming file and field."""
    from coral_core import compose as coral_compose

    try:
        compose_file = coral_compose.find_compose_file(folder)
        project = coral_compose.parse_compose(compose_file, None if environ is None else dict(environ))
    except coral_compose.ComposeError as error:
        raise ConvertError(str(error)) from error
    tree_file = tree or project.tree
    params_file = params or project.params
    if tree_file is None:
        raise ConvertError(f"{folder}: no tree; keep one *.xml beside the compose file or use --tree")
    warnings: list[str] = []
    spec: dict[str, Any] = {"robots": {"matchLabels": selector}}
    groups: dict[str, list[dict[str, Any]]] = {group: [] for group in GROUPS.values()}
    for service in project.services:
        where = f"{compose_file.name}:{service.line}: services.{service.name}"
        component = {"name": component_name(service.name)}
        # `fields` is interpolated as `coral run` reads the file, so both run the same images and paths.
        component |= kubernetes_fields(service.fields, where, warnings)
        if service.role != "executor" and "command" not in service.fields and params_file is not None:
            # Coral's component CLI (coral.sdk) takes the parameters file as --params; the operator
            # mounts the validated file there.
            component["args"] = ["--params", PARAMS_IN_CONTAINER]
        env = [{"name": k, "value": v} for k, v in service.environment.items() if k not in _ROS_ENV]
        if env:
            component["env"] = env
        if service.transient:
            component["transient"] = True
        groups[GROUPS[service.role]].append(component)
    ros = _ros([s.environment for s in project.services])
    if ros:
        spec["ros"] = ros
    tree_text = _read(tree_file)
    params_text = _read(params_file) if params_file else ""
    included = _included_files(tree_file)
    problems = validation.validate_tree(
        tree_text, tree_file.name, files=included, files_label="files"
    ) + validation.validate_parameters(params_text, params_file.name if params_file else "params.yaml")
    if problems:
        raise ConvertError("; ".join(problems))
    rate = project.rate or next((s.rate for s in project.services if s.rate), None)
    main_tree = project.main_tree or next((s.main_tree for s in project.services if s.main_tree), None)
    spec["parameters"] = {"inline": params_text}
    spec["tree"] = {
        "inline": tree_text,
        **({"files": included} if included else {}),
        **({"mainTreeId": main_tree} if main_tree else {}),
        **({"tickRateHz": rate} if rate else {}),
    }
    spec |= groups
    spec["startup"] = {
        "healthTimeoutSeconds": int(project.ready_timeout_s),
        "onTimeout": project.on_timeout.capitalize(),
    }
    try:
        CoralSystemSpec.model_validate(spec)
    except ValidationError as error:
        raise ConvertError(f"{compose_file.name}: {system_pass.format_validation(error)}") from error
    metadata: dict[str, Any] = {"name": naming.dns_label(name or project.name)}
    if namespace:
        metadata["namespace"] = namespace
    manifest = {"apiVersion": API_VERSION, "kind": names.SYSTEM_KIND, "metadata": metadata, "spec": spec}
    return manifest, warnings


def _included_files(tree_file: Path) -> dict[str, str]:
    """The files the tree includes, by name: a CoralSystem carries them in `spec.tree.files`, and the
    operator resolves includes only among them."""
    try:
        document = bt.load_tree_file(tree_file)
    except bt.BTLoadError:
        return {}  # validation reports it with file and line
    folder = tree_file.resolve().parent
    files: dict[str, str] = {}
    for path in document.files[1:]:
        included = Path(path)
        if included.parent != folder:
            raise ConvertError(
                f"{tree_file.name}: includes {path}; a CoralSystem carries only files beside its tree "
                "(spec.tree.files), so keep included files in the tree's folder"
            )
        files[included.name] = _read(included)
    return files


def _read(path: Path) -> str:
    try:
        return parsing.read_text(path)
    except OSError as err:
        raise ConvertError(f"{path}: cannot read: {err.strerror}") from err
    except parsing.NotText as err:
        raise ConvertError(f"{path}:{err.line}: {err.reason}") from err


class _BlockDumper(yaml.SafeDumper):
    def ignore_aliases(self, data: Any) -> bool:
        return True


def _text(dumper: yaml.SafeDumper, value: str) -> yaml.Node:
    return dumper.represent_scalar("tag:yaml.org,2002:str", value, style="|" if "\n" in value else None)


_BlockDumper.add_representer(str, _text)


def render(manifest: dict[str, Any], command: str) -> str:
    """YAML of the manifest with the tree and parameters as readable block scalars."""
    header = f"# Generated by `{command}`; edit the source files and convert again.\n"
    return header + yaml.dump(manifest, Dumper=_BlockDumper, sort_keys=False, width=110)
