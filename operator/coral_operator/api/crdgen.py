"""Renders the CustomResourceDefinitions of `coral.dev` from the pydantic models.

The models are the single source: field docstrings become `description`s (for `kubectl explain`),
pydantic constraints become OpenAPI bounds, `x-kubernetes-validations` in a model's
`json_schema_extra` become CEL rules. Called by `hack/generate-crds.py`, `coral crds` and the test
that fails when `crds/` is stale.
"""

from __future__ import annotations

from typing import Any

import yaml
from coral_core import instance_status, names
from pydantic import BaseModel

from coral_operator.api import common, instance, keys, system

_KEEP = {
    "type",
    "properties",
    "required",
    "items",
    "description",
    "default",
    "enum",
    "format",
    "minimum",
    "maximum",
    "minLength",
    "maxLength",
    "minItems",
    "maxItems",
    "maxProperties",
    "pattern",
    "additionalProperties",
    "x-kubernetes-validations",
    "x-kubernetes-int-or-string",
    "x-kubernetes-list-type",
    "x-kubernetes-list-map-keys",
    "exclusiveMinimum",
    "exclusiveMaximum",
}
# Lists keyed by an item field: the API server refuses duplicates and server-side apply merges them.
# Only on CoralSystems, which people and GitOps tools write. A CoralInstance is written by the
# operator and its robot's executor alone, both with merge patches that replace a list whole, and
# keyed lists there cost every write: the API server tracks each item's fields in managedFields
# (3.2 of a 7.3 kB instance), and a status patch took 12.2 ms of its CPU against 9.6 ms with
# plain lists, a create 6.7 against 5.9 ms (alternating rounds of 200 on one control plane).
_MAP_LISTS = {"conditions": "type", "drivers": "name", "skillsets": "name", "executors": "name"}


def _resolve(node: dict[str, Any], defs: dict[str, Any]) -> dict[str, Any]:
    if "$ref" in node:
        target = dict(defs[node["$ref"].split("/")[-1]])
        extra = {k: v for k, v in node.items() if k != "$ref"}
        return {**target, **extra}
    return node


def _convert(node: dict[str, Any], defs: dict[str, Any], map_lists: dict[str, str]) -> dict[str, Any]:
    """One pydantic JSON-schema node to a structural OpenAPI v3 node; the list properties named in
    `map_lists` are keyed by the item field it gives."""
    node = _resolve(node, defs)
    if "anyOf" in node:
        branches = [_resolve(b, defs) for b in node["anyOf"]]
        non_null = [b for b in branches if b.get("type") != "null"]
        types = sorted(b.get("type", "") for b in non_null)
        outer = {k: v for k, v in node.items() if k not in ("anyOf", "default")}
        if node.get("default") is not None:
            outer["default"] = node["default"]
        if types == ["integer", "string"]:
            return _convert({**outer, "x-kubernetes-int-or-string": True}, defs, map_lists)
        if len(non_null) != 1:
            raise ValueError(f"cannot express union {types} in a structural schema")
        return _convert({**non_null[0], **outer}, defs, map_lists)
    if "const" in node:
        node = {**{k: v for k, v in node.items() if k != "const"}, "enum": [node["const"]]}
    if node.get("x-kubernetes-int-or-string"):
        node = {k: v for k, v in node.items() if k != "type"}
    out: dict[str, Any] = {}
    for key, value in node.items():
        if key not in _KEEP:
            continue
        if key == "properties":
            out[key] = {name: _convert(child, defs, map_lists) for name, child in value.items()}
            for name, child in out[key].items():
                if name in map_lists and child.get("type") == "array":
                    child["x-kubernetes-list-type"] = "map"
                    child["x-kubernetes-list-map-keys"] = [map_lists[name]]
        elif key == "items":
            out[key] = _convert(value, defs, map_lists)
        elif key == "additionalProperties":
            if isinstance(value, dict):
                out[key] = _convert(value, defs, map_lists)
        elif key in ("exclusiveMinimum", "exclusiveMaximum"):
            # JSON Schema 2020 gives the bound; OpenAPI v3.0 wants the bound plus a flag.
            bound = "minimum" if key == "exclusiveMinimum" else "maximum"
            out[bound] = value
            out[key] = True
        elif key == "description":
            out[key] = " ".join(str(value).split())
        else:
            out[key] = value
    if out.get("type") == "object" and "properties" in out:
        required = set(out.get("required", []))
        for name, child in out["properties"].items():
            # A non-optional nested object or list gets an empty default so the defaults inside
            # it apply even when the user leaves it out.
            if name not in required and "default" not in child and not _was_optional(node, name, defs):
                if child.get("type") == "object":
                    child["default"] = _defaults_of(child)
                elif child.get("type") == "array":
                    child["default"] = []
    return out


def _defaults_of(node: dict[str, Any]) -> dict[str, Any]:
    # The API server checks a default against the CEL rules as it is, without filling in the
    # nested defaults, so an object default must spell them out.
    return {
        name: child["default"] for name, child in node.get("properties", {}).items() if "default" in child
    }


def _was_optional(node: dict[str, Any], name: str, defs: dict[str, Any]) -> bool:
    raw = node.get("properties", {}).get(name, {})
    return any(_resolve(b, defs).get("type") == "null" for b in raw.get("anyOf", []))


def build_schema(model: type[BaseModel], *, keyed_lists: bool = True) -> dict[str, Any]:
    """The structural OpenAPI v3 schema of one pydantic model; `keyed_lists`: its condition and
    component lists are keyed (`_MAP_LISTS`)."""
    raw = model.model_json_schema(by_alias=True, mode="validation")
    return _convert(raw, raw.get("$defs", {}), _MAP_LISTS if keyed_lists else {})


def _status_path(*wire_names: str) -> str:
    return ".status." + ".".join(wire_names)


def _column(name: str, kind: str, *wire_names: str, wide: bool = False) -> dict[str, Any]:
    """A printer column over a status field; `wide` ones show only with `-o wide`."""
    column: dict[str, Any] = {"name": name, "type": kind, "jsonPath": _status_path(*wire_names)}
    if wide:
        column["priority"] = 1
    return column


def _condition_column(
    name: str, ctype: str, field: str = keys.CONDITION.status, priority: int = 0
) -> dict[str, Any]:
    # Both kinds' status call their condition list alike.
    conditions = _status_path(keys.SYSTEM_STATUS.conditions)
    column = {
        "name": name,
        "type": "string",
        "jsonPath": f'{conditions}[?(@.{keys.CONDITION.type}=="{ctype}")].{field}',
    }
    if priority:
        column["priority"] = priority
    return column


def _crd(
    *,
    kind: str,
    plural: str,
    short_names: list[str],
    description: str,
    spec_model: type[BaseModel],
    status_model: type[BaseModel],
    columns: list[dict[str, Any]],
    keyed_lists: bool,
) -> dict[str, Any]:
    spec_schema = build_schema(spec_model, keyed_lists=keyed_lists)
    status_schema = build_schema(status_model, keyed_lists=keyed_lists)
    schema = {
        "type": "object",
        "description": description,
        "required": ["spec"],
        "properties": {
            "apiVersion": {"type": "string", "description": "Versioned schema of this object."},
            "kind": {"type": "string", "description": "Kind of this object."},
            "metadata": {"type": "object"},
            "spec": spec_schema,
            # A new object is in progress until the operator says otherwise (api.common.pending_status).
            "status": {**status_schema, "default": common.pending_status()},
        },
    }
    return {
        "apiVersion": "apiextensions.k8s.io/v1",
        "kind": "CustomResourceDefinition",
        "metadata": {"name": f"{plural}.{names.GROUP}"},
        "spec": {
            "group": names.GROUP,
            "scope": "Namespaced",
            "names": {
                "kind": kind,
                "listKind": f"{kind}List",
                "plural": plural,
                "singular": kind.lower(),
                "shortNames": short_names,
                "categories": ["coral"],
            },
            "versions": [
                {
                    "name": names.VERSION,
                    "served": True,
                    "storage": True,
                    "subresources": {"status": {}},
                    "additionalPrinterColumns": [
                        *columns,
                        {"name": "Age", "type": "date", "jsonPath": ".metadata.creationTimestamp"},
                    ],
                    "schema": {"openAPIV3Schema": schema},
                }
            ],
        },
    }


def build_crds() -> dict[str, dict[str, Any]]:
    """File name -> CRD manifest, for every kind of `coral.dev`."""
    systems = _crd(
        kind=names.SYSTEM_KIND,
        plural=names.SYSTEM_PLURAL,
        short_names=["csys", "coralsys"],
        description="A Coral system (behavior tree, components, ROS parameters) and the robots it runs on.",
        spec_model=system.CoralSystemSpec,
        status_model=system.CoralSystemStatus,
        keyed_lists=True,
        columns=[
            _column("Robots", "integer", keys.SYSTEM_STATUS.robots, keys.ROBOT_COUNTS.matched),
            _column("Ready", "integer", keys.SYSTEM_STATUS.robots, keys.ROBOT_COUNTS.ready),
            _column("Updated", "integer", keys.SYSTEM_STATUS.robots, keys.ROBOT_COUNTS.updated),
            _column("Unreachable", "integer", keys.SYSTEM_STATUS.robots, keys.ROBOT_COUNTS.unreachable),
            _condition_column("Status", "Ready", keys.CONDITION.reason),
            _column("Running", "integer", keys.SYSTEM_STATUS.trees, keys.TREE_COUNTS.running, wide=True),
            _column("Failed", "integer", keys.SYSTEM_STATUS.trees, keys.TREE_COUNTS.failure, wide=True),
            _column("Revision", "string", keys.SYSTEM_STATUS.revision, wide=True),
        ],
    )
    instances = _crd(
        kind=names.INSTANCE_KIND,
        plural=names.INSTANCE_PLURAL,
        short_names=["cinst", "coralinst"],
        description="One robot's share of a CoralSystem: its component pods and its behavior-tree status.",
        spec_model=instance.CoralInstanceSpec,
        status_model=instance_status.CoralInstanceStatus,
        keyed_lists=False,
        columns=[
            {"name": "Robot", "type": "string", "jsonPath": ".spec.robot"},
            _condition_column("Ready", "Ready"),
            _condition_column("Reachable", "RobotReachable"),
            _column("Tree", "string", keys.INSTANCE_STATUS.tree, keys.TREE.root_status),
            _column("Active", "string", keys.INSTANCE_STATUS.tree, keys.TREE.active_path, wide=True),
            _column("Ticks", "integer", keys.INSTANCE_STATUS.tree, keys.TREE.tick_count, wide=True),
            {"name": "Revision", "type": "string", "jsonPath": ".spec.revision", "priority": 1},
            {"name": "Config", "type": "string", "jsonPath": ".spec.configHash", "priority": 1},
            {"name": "Node", "type": "string", "jsonPath": ".spec.nodeName", "priority": 1},
        ],
    )
    return {
        f"{names.GROUP}_{names.SYSTEM_PLURAL}.yaml": systems,
        f"{names.GROUP}_{names.INSTANCE_PLURAL}.yaml": instances,
    }


class _NoAliases(yaml.SafeDumper):
    def ignore_aliases(self, data: Any) -> bool:
        return True


def render(manifest: dict[str, Any]) -> str:
    """YAML text of one CRD, stable across runs."""
    header = "# Generated from operator/coral_operator/api by hack/generate-crds.py; do not edit.\n"
    return header + yaml.dump(manifest, Dumper=_NoAliases, sort_keys=True, width=100)
